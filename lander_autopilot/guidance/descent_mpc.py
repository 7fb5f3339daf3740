"""Model predictive control of the powered descent: the minimum-fuel descent, re-planned each period.

Plain numpy and cvxpy (no rclpy). Local frame as in :mod:`.fuel_optimal` (origin on the surface below
the target, z up; m, m/s, N, kg).

Each control period the controller solves one convex programme over ``H`` prediction steps that end
where the fuel-optimal reference ends (``h = max(t_f - t, min_time_to_go) / H``): a point mass
``x = (r, v)`` under uniform gravity and drag, the command an acceleration ``a = T / m`` held over
each step::

    minimise   sum_k m_k h |a_k|  +  W |end miss|_1                 (impulse = fuel / alpha; exact penalty)
    subject to v_{k+1} = v_k + h (a_k + a_D(v_k, v_{k+1}) + g_L),   r_{k+1} = r_k + h (v_k + v_{k+1}) / 2,
               x_0 = the measured state,
               |a_k| <= f (1 - r_k) rho_max / m_k,   a_k . z >= |a_k| cos(max_tilt),   (thrust, pointing)
               |r_k - target|_xy tan(glide_slope) <= (r_k - target)_z    (glide slope),
               r_k . z >= 0                                             (never below the surface)

``m_k`` is the mass predicted as the reference burns, ``f`` the plan's thrust fraction (0.99: 1 % of
authority for what the model does not know), ``r_k = plan_reserve min(k h / reserve_time, 1)`` the
bound's tightening with the time ahead (none by default): the step flown now may use the whole
bound, the plan's later steps keep the reserve in hand, so that a fall that gets behind the plan
(a gust, the drag model's error) finds the thrust to catch up. The fuel-optimal QP brakes as late
as its bound allows, so any slack between its bound and the reference is spent on braking later,
and only a reserve it may not plan on stays a margin (the de-orbit law keeps 4 %,
:class:`..controllers.deorbit_mpc.DeorbitMpcController`). The command is the plan's mean over the
period it is flown (``hold_time``): at the end the steps are shorter than the period. The end miss is the distance from rest at the target
(its altitude only, with ``free_horizontal``): an exact (L1) penalty, so the end is met exactly when
it can be and the nearest miss is flown when it cannot, and every period's problem is feasible.

Drag (:class:`.fuel_optimal.DragModel`, the open chute's and the body's) is linearised about the
reference at each step's midpoint (about the measured state for the first step) and applied to the
step's mean velocity: the QP stays a QP, it sees that a faster fall brakes more for free (which is
what makes the optimum coast and then burn late), and it does not overstate the braking of a step
at full thrust (drag at the step's start did, by ~9 N, and the plan ended 1-2 m low).

The reference is the minimum-fuel descent from the handover state (:func:`.fuel_optimal.solve`,
lossless convexification, free final time), solved once at ``reference_thrust_fraction`` of the
thrust: it fixes the end time ``t_f`` and the drag's linearisation points. Under the chute the
de-orbit law solves it at 0.94 (:class:`..controllers.deorbit_mpc.DeorbitMpcController`'s
``reference_thrust``), under its plan's bound with the reserve kept (0.99 x 0.96). Without drag the longer end time is pure
gravity loss (1.095 x against 1.03 x at 0.99 in ``test_descent_mpc.py``), hence the default 0.99. The end does not recede
(a receding end gave the plan slack: it eased off, arrived late and low, 1.06 x); only in its last
``min_time_to_go`` does it.

In its last ``limb_time`` s (1 s by default, as the de-orbit law's; 0: never) the vertical command is bounded
by the constant deceleration to rest at the target from the measured state (the limb,
:meth:`DescentMpc.limb_acceleration`): never more than it, and the limb itself once it needs the
thrust the plan brakes on (:meth:`DescentMpc._last_second`). There the plan is degenerate along the
vertical and, once its end recedes, coasts and brakes late period after period.

The thrust axis is not instant: the attitude loop turns it with a lag, and under a canopy in a
wind the minimum-fuel plan brakes the drift late (early on, the canopy's drag pulls the lander
back toward the wind's speed), where a lag of ~1 s matters. With ``attitude_lag`` > 0 the QP's
horizontal thrust acceleration flown relaxes toward the commanded one over that time constant,
from what the body's axis gives at the start (exact over each step), so the QP commands ahead of
the lag. Planned as instant, the 200 km scene's dispersed descents began the hover with up to
1 m/s of drift (median fuel 1.11 x the optimum over 30 cases; with the lag 1.03 x).

Why minimum fuel and not tracking: a tracking MPC (quadratic cost about the reference at 0.97 of the
thrust) flies 1.042 x the optimum from the common handover case: smoothing the reference's bang-bang switch
and its late end cost 3 %. Minimising the fuel itself flies 1.004 x there.

Why this solver: the fuel is a sum of second-order-cone norms and the thrust and pointing limits are
cones too, so each period's problem is an SOCP, which Clarabel (interior point, installed with the
project) solves natively and to high accuracy. OSQP needs a QP (the cones replaced by polyhedra: an
inner approximation costs thrust, an outer one violates the limit); do-mpc would add a CasADi/IPOPT
stack for a problem that is convex anyway.

Why this call, in a control period of 0.1 s on a machine whose two cores also fly the simulation:
the programme is written once with cvxpy parameters in DPP form (each product of the step with the
drag's linearisation is a parameter of its own: a parameter times a parameter times a variable is
not DPP, and cvxpy then compiles the whole programme anew at every call), canonicalised once
(:class:`MpcProgramme`, built with the controller before the flight: the modelling layer's import,
~1-2 s the first time in a process, and the canonicalisation, 25-50 ms, stay out of the period that
hands over), and each period handed to Clarabel directly (:class:`.conic_program.ConicProgram`: the parameters times
cvxpy's own sparse data tensor, then a fresh solver; the same data and the same answer as cvxpy's
Clarabel interface, to the bit). What is left per period is Clarabel's own iterations (~10) and its
set-up: over the de-orbit sweeps' MPC flights ~2 ms at the median, p99 7 ms, worst 9 ms with the
cores shared three to four ways; compiled each period the same programme took 5-8 times that at the
median and single periods of 0.3 s (``bench/guidance_mpc.py``, both side by side). Left aside: a solver generated for the fixed shape (cvxpygen, QOCOGEN) would add a C build
to the set-up to shorten what is already well inside the period; warm starts, which an
interior-point method cannot use (it starts from its own central point).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .conic_program import ConicProgram
from .fuel_optimal import DescentLimits, DescentProblem, DescentSolution, DragModel, GuidanceError, drag_up, solve

#: [-] default thrust bound of the reference and of each period's programme, of ``rho_max``: the
#: last percent is left for the feedback on the plan's errors (the attitude law's differential)
THRUST_FRACTION = 0.99
#: [s] the shortest horizon, once the reference's end is (nearly) passed: three control periods,
#: steps of 15 ms at ``H = 20``
MIN_TIME_TO_GO = 0.3
#: [s] how long a command is flown: the autopilot's 10 Hz control period
HOLD_TIME = 0.1
#: [-] end miss weight, times the mass: impulse [kg m/s] per m (or m/s) missed. Against the fuel a
#: missed metre can save (of order sqrt(2 g x 1 m) ~ 3 m/s per kg) it is large, so the end is met
#: whenever the limits allow; soft, so a state that cannot reach it still gets a plan
END_PENALTY = 100.0
#: [s] the reference's final time needs no more precision than a control period's share: fuel is
#: flat near its optimum
REFERENCE_TIME_TOLERANCE = 1e-3


@dataclass(frozen=True)
class MpcSettings:
    """Horizon, margins and end penalty of :class:`DescentMpc` (SI units)."""

    horizon_steps: int = 20
    reference_thrust_fraction: float = THRUST_FRACTION  # the reference's thrust bound, of rho_max (sets the end time)
    reference_steps: int = 60
    plan_thrust_fraction: float = THRUST_FRACTION  # the QP's thrust bound, of rho_max: authority left for the feedback
    plan_reserve: float = 0.0  # share of that bound the plan keeps in reserve, reserve_time ahead and later
    reserve_time: float = 1.0  # s: the reserve grows linearly to plan_reserve over this much of the plan
    min_time_to_go: float = MIN_TIME_TO_GO  # s: the shortest horizon, once the reference's end is (nearly) passed
    # s: how long the command is flown (the control period). Where the plan's steps are shorter (at
    # the end: min_time_to_go / H, 15 ms), the command is the plan's mean over that time: its first
    # 15 ms step alone, flown for 100 ms, let the fall run on (a light first step before full thrust)
    # and the full thrust after it overshot into a climb (0.75 m/s; 1.054 x with a 4 % plan_reserve)
    hold_time: float = HOLD_TIME
    end_penalty: float = END_PENALTY  # end miss weight, x mass: impulse [kg m/s] per m (or m/s) missed, per kg
    attitude_lag: float = 0.0  # s: time constant of the thrust axis following the command (0: instant)
    # s: in this much before the reference's end, while falling, the vertical command is bounded by
    # the constant deceleration to rest at the target (:meth:`DescentMpc._last_second`; 0: never)
    limb_time: float = 1.0

    def __post_init__(self) -> None:
        if self.horizon_steps < 2:
            raise GuidanceError(f"horizon_steps must be >= 2, got {self.horizon_steps}")
        if not (0 < self.reference_thrust_fraction <= 1):
            raise GuidanceError(f"reference_thrust_fraction must be in (0, 1], got {self.reference_thrust_fraction}")
        if not (0 < self.plan_thrust_fraction <= 1):
            raise GuidanceError(f"plan_thrust_fraction must be in (0, 1], got {self.plan_thrust_fraction}")
        if not (0 <= self.plan_reserve < 1):
            raise GuidanceError(f"plan_reserve must be in [0, 1), got {self.plan_reserve}")
        for name in ("min_time_to_go", "hold_time", "end_penalty", "reserve_time"):
            if not (getattr(self, name) > 0):
                raise GuidanceError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("attitude_lag", "limb_time"):
            if not (getattr(self, name) >= 0):
                raise GuidanceError(f"{name} must be >= 0 s, got {getattr(self, name)}")


@dataclass
class MpcStats:
    """Solve times of every period so far [s] and how many solves failed (the last command was held)."""

    solve_times: list[float] = field(default_factory=list)
    failures: int = 0

    def percentile(self, q: float) -> float:
        return float(np.percentile(self.solve_times, q)) if self.solve_times else math.nan


class Reference:
    """The fuel-optimal descent as a function of time, then a hover at the target."""

    def __init__(self, solution: DescentSolution, gravity: float, target_L: np.ndarray) -> None:
        self.sol, self.g, self.target = solution, gravity, np.asarray(target_L, float)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference (position, velocity, acceleration = T / m) at ``t`` s after the handover."""
        s = self.sol
        if t >= s.final_time:
            return self.target.copy(), np.zeros(3), np.array([0.0, 0.0, self.g])
        t = max(t, 0.0)
        k = min(int(t / (s.final_time / (len(s.t) - 1))), len(s.t) - 2)
        w = (t - s.t[k]) / (s.t[k + 1] - s.t[k])
        acc = s.thrust_L / s.mass[:, None]
        def lerp(a: np.ndarray) -> np.ndarray:
            return (1 - w) * a[k] + w * a[k + 1]

        # position and velocity interpolated linearly between nodes: their error is O(dt^2) of the
        # reference's own discretisation, well under what the feedback corrects
        return lerp(s.position_L), lerp(s.velocity_L), lerp(acc)

    def along(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference positions and velocities, rows ``(len(times), 3)``, at each of ``times`` s after the
        handover: :meth:`at`'s interpolation, for many times at once (each period's drag points)."""
        s = self.sol
        t = np.maximum(np.asarray(times, float), 0.0)
        k = np.minimum((t / (s.final_time / (len(s.t) - 1))).astype(int), len(s.t) - 2)
        w = ((t - s.t[k]) / (s.t[k + 1] - s.t[k]))[:, None]
        pos = (1 - w) * s.position_L[k] + w * s.position_L[k + 1]
        vel = (1 - w) * s.velocity_L[k] + w * s.velocity_L[k + 1]
        after = t >= s.final_time
        pos[after], vel[after] = self.target, 0.0
        return pos, vel


class MpcProgramme:
    """The receding-horizon programme (module docstring) for a horizon, pointing and glide-slope
    limits and an end, written once in cvxpy (DPP) and canonicalised once
    (:class:`.conic_program.ConicProgram`): what is left per period is one Clarabel solve. It holds
    no flight: every parameter, the target's included, is set before each solve
    (:meth:`DescentMpc.command`), so one programme serves every handover of a controller, and
    building it (the modelling layer's import and canonicalisation, tens of milliseconds and more)
    is done before the flight, not in the period that hands over to it.
    """

    def __init__(self, settings: MpcSettings, max_tilt: float, glide_slope: float, free_horizontal: bool) -> None:
        import cvxpy as cp

        self.settings = st = settings
        self.max_tilt, self.glide_slope, self.free_horizontal = float(max_tilt), float(glide_slope), bool(free_horizontal)
        H = st.horizon_steps
        # The step is a parameter: the horizon shrinks to the reference's end (exact discretisation of
        # r'' = a + a_drag + g_L with a held over a step of h s: h and h^2/2 enter linearly, DPP)
        self.h = cp.Parameter(nonneg=True)
        self.hh = cp.Parameter(nonneg=True)
        self.x0 = cp.Parameter(6)
        self.target = cp.Parameter(3)  # [m, local] where the plan ends at rest
        self.amax = cp.Parameter(H, nonneg=True)  # thrust bound / predicted mass, each step
        self.fuel_w = cp.Parameter(H, nonneg=True)  # predicted mass x h: sum w |a| = the impulse (fuel / alpha)
        # drag acceleration over each predicted step, linearised about the reference: a_D(v) ~
        # d0 + D v (D the diagonal of d a_D / d v), so that the QP sees that a faster fall brakes more
        # for free (what makes the optimum coast and then burn late). Each enters times h and h^2/2,
        # as parameters of their own (h (d0 + g_L), h D, ...): a parameter times a parameter times a
        # variable is not DPP, and cvxpy would then compile the whole programme again every period
        self.push_h = cp.Parameter((H, 3))  # h (d0 + g_L): velocity gained over the step without thrust
        self.push_hh = cp.Parameter((H, 3))  # h^2/2 (d0 + g_L): its share of the step's displacement
        self.slow_h = cp.Parameter((H, 3), nonpos=True)  # h D: the drag's slope on the step's mean velocity
        self.slow_hh = cp.Parameter((H, 3), nonpos=True)  # h^2/2 D
        self.end_w = cp.Parameter(nonneg=True)
        x = cp.Variable((H + 1, 6))
        a = cp.Variable((H, 3))
        lag_cons = []
        if st.attitude_lag > 0:
            # The thrust axis follows the command with a lag (the attitude loop's): the horizontal
            # thrust acceleration flown, r, relaxes toward the commanded one, exactly over each step
            # (keep = exp(-h / lag)), from what the body's axis gives now; the QP commands ahead of it.
            r = cp.Variable((H + 1, 2))
            self.r0 = cp.Parameter(2)
            self.keep = cp.Parameter(nonneg=True)
            self.gain = cp.Parameter(nonneg=True)
            lag_cons = [r[0] == self.r0, r[1:] == self.keep * r[:-1] + self.gain * a[:, :2]]
            thrust = cp.hstack([(r[:-1] + r[1:]) / 2, a[:, 2:3]])
        else:
            thrust = a
        # drag at each step's mean velocity (trapezoidal): the fall slows by ~8 m/s over a 0.45 s step at
        # full thrust, and drag at the step's start overstated the braking (the plan ended ~2 m low)
        v_mean = (x[:-1, 3:] + x[1:, 3:]) / 2
        cons = lag_cons + [x[0] == self.x0,
                x[1:, :3] == (x[:-1, :3] + self.h * x[:-1, 3:] + self.hh * thrust + self.push_hh
                              + cp.multiply(self.slow_hh, v_mean)),
                x[1:, 3:] == x[:-1, 3:] + self.h * thrust + self.push_h + cp.multiply(self.slow_h, v_mean),
                cp.norm(a, axis=1) <= self.amax,
                a[:, 2] >= math.cos(max_tilt) * cp.norm(a, axis=1),
                x[:, 2] >= 0]
        if glide_slope > 0 and not free_horizontal:
            rel = x[:, :3] - np.ones((H + 1, 1)) @ cp.reshape(self.target, (1, 3), order="C")
            # the state at the handover may already be outside the cone: only the predicted steps
            cons.append(cp.norm(rel[1:, :2], axis=1) * math.tan(glide_slope) <= rel[1:, 2])
        # The end state as an exact (L1) penalty: at rest at the target when that is reachable (the
        # penalty's weight is far above the fuel's price of a metre or a m/s), the nearest miss when
        # it is not, so that every period's problem is feasible. The miss is a variable of its own:
        # the weight (a parameter) times a norm of the target (a parameter) would not be DPP.
        rest = np.r_[0.0, 0.0, 0.0]
        end = (x[H, 2:] - cp.hstack([self.target[2:3], rest]) if free_horizontal
               else x[H] - cp.hstack([self.target, rest]))
        miss = cp.Variable(end.shape[0])
        cons.append(miss == end)
        cost = cp.sum(cp.multiply(self.fuel_w, cp.norm(a, axis=1))) + self.end_w * cp.norm1(miss)
        self.a = a
        self.program = ConicProgram(cp.Problem(cp.Minimize(cost), cons))

    def fits(self, settings: MpcSettings, limits: DescentLimits, free_horizontal: bool) -> bool:
        """Whether this programme is the one ``settings``, ``limits`` and ``free_horizontal`` pose
        (horizon, lag, pointing and glide-slope limits, end): the rest enters as parameters."""
        st = self.settings
        return (st.horizon_steps == settings.horizon_steps and (st.attitude_lag > 0) == (settings.attitude_lag > 0)
                and self.max_tilt == limits.max_tilt and self.glide_slope == limits.glide_slope
                and self.free_horizontal == free_horizontal)


class DescentMpc:
    """The receding-horizon law; :meth:`command` gives the thrust vector to fly now.

    ``free_horizontal``: the descent ends in a hover at ``target_L``'s altitude wherever the
    fuel-optimal reference ends it (no landing spot), which then is the target. ``programme``: the
    :class:`MpcProgramme` to solve each period (built here when not given; one given must fit
    ``settings``, ``limits`` and ``free_horizontal``).
    """

    def __init__(self, position_L: np.ndarray, velocity_L: np.ndarray, mass: float, gravity: float,
                 limits: DescentLimits, target_L: np.ndarray | None = None,
                 settings: MpcSettings | None = None, free_horizontal: bool = False,
                 drag: DragModel | None = None, programme: MpcProgramme | None = None) -> None:
        self.settings = st = settings or MpcSettings()
        if programme is not None and not programme.fits(st, limits, free_horizontal):
            raise GuidanceError("the MPC programme given was built for another horizon, lag, limits or end")
        self.limits, self.g = limits, float(gravity)
        self.target = np.zeros(3) if target_L is None else np.asarray(target_L, float)
        ref_limits = DescentLimits(rho_max=limits.rho_max * st.reference_thrust_fraction, alpha=limits.alpha,
                                   dry_mass=limits.dry_mass, rho_min=limits.rho_min, max_tilt=limits.max_tilt,
                                   glide_slope=limits.glide_slope)
        # The final time needs no more precision than a control period: fuel is flat near its optimum.
        reference = solve(DescentProblem(position_L=position_L, velocity_L=velocity_L, mass=mass,
                                         gravity=gravity, limits=ref_limits, target_L=self.target,
                                         free_horizontal=free_horizontal, drag=drag),
                          steps=st.reference_steps, t_tol=REFERENCE_TIME_TOLERANCE)
        if free_horizontal:  # a hover wherever the optimum ends it: that point is the target
            self.target = np.array(reference.position_L[-1])
        self.reference = Reference(reference, gravity, self.target)
        self.drag = drag
        self.stats = MpcStats()
        self.programme = programme or MpcProgramme(st, limits.max_tilt, limits.glide_slope, free_horizontal)
        self._last = self.reference.at(0.0)[2]

    def command(self, t: float, position_L: np.ndarray, velocity_L: np.ndarray, mass: float,
                thrust_axis_L: np.ndarray | None = None, available: float = 1.0) -> np.ndarray:
        """Thrust vector [N, local frame] to hold until the next period; ``t`` s after the handover.

        ``thrust_axis_L``: the body's thrust axis now (unit, local frame), where the horizontal thrust
        flown starts from with ``attitude_lag`` (default: the last command's direction).
        ``available``: fraction of ``rho_max`` the thrusters can give now (the rest is the attitude
        law's, :class:`lander_autopilot.controllers.combined.CollectiveHeadroom`).
        """
        st = self.settings
        H = st.horizon_steps
        sol = self.reference.sol
        # The horizon ends where the reference does: a fixed end leaves the plan no slack to spend
        # (a receding end let it ease off and arrive late and low). Only in its last min_time_to_go
        # does the end recede, so that the problem keeps a horizon.
        h = max(sol.final_time - t, st.min_time_to_go) / H
        tk = t + h * np.arange(H)
        ref_mass = np.interp(tk, sol.t, sol.mass)
        m_k = np.maximum(mass - (ref_mass[0] - ref_mass), self.limits.dry_mass)  # burning as the reference does
        q = self.programme
        put = q.program.set
        put(q.target, self.target)
        put(q.h, h)
        put(q.hh, h * h / 2)
        put(q.x0, np.r_[position_L, velocity_L])
        amax = st.plan_thrust_fraction * available * self.limits.rho_max / m_k
        # tightened with the time ahead (what a disturbance can have done by then grows with it): the
        # step flown now may use the whole bound, a step reserve_time or more ahead keeps plan_reserve
        amax *= 1.0 - st.plan_reserve * np.minimum(h * np.arange(H) / st.reserve_time, 1.0)
        put(q.amax, amax)
        put(q.fuel_w, m_k * h)
        put(q.end_w, st.end_penalty * mass)
        if st.attitude_lag > 0:
            keep = math.exp(-h / st.attitude_lag)
            put(q.keep, keep)
            put(q.gain, 1.0 - keep)
            put(q.r0, float(np.linalg.norm(self._last)) * np.asarray(thrust_axis_L, float)[:2]
                if thrust_axis_L is not None else self._last[:2])
        if self.drag is None:
            d0, dv = np.zeros((H, 3)), np.zeros((H, 3))
        else:
            # about the reference, except the first step: about the measured state
            pos, vel = self.reference.along(tk + h / 2)
            pos[0], vel[0] = position_L, velocity_L
            dv = np.minimum(np.diagonal(self.drag.jacobian(pos, vel, m_k), axis1=1, axis2=2), 0.0)
            d0 = self.drag.acceleration(pos, vel, m_k) - dv * vel
        push = d0 + np.array([0.0, 0.0, -self.g])
        put(q.push_h, h * push)
        put(q.push_hh, (h * h / 2) * push)
        put(q.slow_h, h * dv)
        put(q.slow_hh, (h * h / 2) * dv)
        t0 = time.perf_counter()
        ok = q.program.solve()
        self.stats.solve_times.append(time.perf_counter() - t0)
        if ok:
            n = min(max(int(round(st.hold_time / h)), 1), H)  # the plan's steps the command is flown over
            self._last = np.array(q.program.value(q.a)[:n].mean(axis=0))
        else:
            self.stats.failures += 1  # hold the last command: the next period tries again
        acc = self._last
        if st.limb_time > 0.0 and sol.final_time - t <= st.limb_time and velocity_L[2] < 0.0:
            acc = self._last_second(acc, position_L, velocity_L, mass, available)
        return acc * mass

    def _last_second(self, acc: np.ndarray, position_L: np.ndarray, velocity_L: np.ndarray, mass: float,
                     available: float) -> np.ndarray:
        """The command ``acc`` [m/s^2, local] of the plan's last ``limb_time`` s with its vertical part
        bounded by the limb (:meth:`limb_acceleration`, the constant deceleration to rest at the target):
        never more than the limb needs (braking harder only stops the fall early, over the target,
        and the rest is flown down on gravity loss), and once the limb needs the thrust the plan
        brakes on (its bound with the reserve kept), the limb's (the plan would coast a period and
        brake late, period after period). Under the target, all the thrust along up."""
        need = self.limb_acceleration(position_L, velocity_L, mass)
        if not math.isfinite(need):
            return np.array([0.0, 0.0, self.limits.rho_max / mass])
        st = self.settings
        brakes_on = st.plan_thrust_fraction * (1.0 - st.plan_reserve) * available * self.limits.rho_max / mass
        return np.array([acc[0], acc[1], need if need >= brakes_on else min(float(acc[2]), need)])

    def limb_acceleration(self, position_L: np.ndarray, velocity_L: np.ndarray, mass: float) -> float:
        """The vertical thrust acceleration [m/s^2, up] that stops a fall (``velocity_L[2] < 0``) at rest
        at the target's altitude at constant deceleration: ``g - a_D,up + v_z^2 / (2 dz)``, ``dz`` the
        height over the target and ``a_D,up`` the plan's drag now. At or under the target it is
        unbounded (``inf``, the formula's limit as ``dz`` goes to 0): :meth:`command` then asks for all
        the thrust along up, stopping the fall before the drift (the caller caps what would turn the
        fall into a climb within a period).

        Why, in the plan's last ``limb_time`` s (:meth:`_last_second`): there the minimum-fuel plan
        is degenerate (along the vertical, with the end time fixed and little drag, every thrust
        profile that stops at the target costs the same impulse), and once its end recedes (the last
        ``min_time_to_go``) it coasts and then brakes late, period after period. The flights ended
        in a wobble of light and full periods, or with the plan's bound (the reserve, the attitude
        law's share) braking on less than the thrusters give while the fall ran past the target
        (test/guidance/test_descent_mpc.py,
        ``test_the_last_second_stops_the_fall_at_constant_deceleration_nearer_the_target_for_less_fuel``)."""
        dz = float(position_L[2]) - float(self.target[2])
        if dz <= 0.0:
            return math.inf
        return self.g - drag_up(self.drag, position_L, velocity_L, mass) + float(velocity_L[2]) ** 2 / (2.0 * dz)
