"""Model predictive control of the powered descent: track the fuel-optimal reference, within the limits.

Plain numpy and cvxpy (no rclpy). Local frame as in :mod:`.fuel_optimal` (origin on the surface below
the target, z up; m, m/s, N, kg).

Each control period the controller solves one convex programme over a horizon of ``H`` prediction
steps of ``h`` s: a point mass ``x = (r, v)`` under uniform gravity, the command an acceleration
``a = T / m`` held over each step (exact discretisation of the double integrator)::

    minimise   sum_k |x_k - x_ref(t_k)|_Q^2 + |a_k - a_ref(t_k)|_R^2 + |x_H - x_ref(t_H)|_P^2
    subject to x_{k+1} = Phi x_k + Gamma (a_k + g_L),  x_0 = the measured state,
               |a_k| <= rho_max / m,   a_k . z >= |a_k| cos(max_tilt),   (thrust and pointing limits)
               |r_k - target|_xy tan(glide_slope) <= (r_k - target)_z    (glide slope),
               r_k . z >= 0                                             (never below the surface)

With ``drag`` (:class:`.fuel_optimal.DragModel`, e.g. the open chute's) the reference is the
minimum-fuel descent with that drag, and the prediction adds the drag acceleration along the
reference (at the measured state for the first step) as a known term: the QP stays a QP, and the
feedback takes up the difference between the reference's drag and the true one.

The reference is the minimum-fuel descent from the handover state (:func:`.fuel_optimal.solve`),
solved once with a thrust margin (``reference_thrust_fraction``, default 0.97 of ``rho_max``) so
that the feedback has authority left when the vehicle is off the reference; past its end it is a
hover at the target. Tracking it keeps the fuel close to the optimum.

Why this solver: the objective is quadratic and the exact thrust and pointing limits are second-order
cones, so each period's problem is a QP with cone constraints, which Clarabel (interior point,
installed with the project) solves natively and to high accuracy in a few ms for ``H = 20``. OSQP
would need the cones replaced by polyhedra (an inner approximation costs thrust, an outer one
violates the limit); do-mpc would add a CasADi/IPOPT stack for a problem that is convex anyway.
The problem is built once with cvxpy parameters (DPP), so a period costs one solve, no compilation.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .fuel_optimal import DescentLimits, DescentProblem, DescentSolution, DragModel, GuidanceError, solve


@dataclass(frozen=True)
class MpcSettings:
    """Horizon, weights and margins of :class:`DescentMpc` (SI units)."""

    horizon_steps: int = 20
    step: float = 0.5  # prediction step h [s]
    # Weights measured on the honest endpoint (fuel to the first instant within 2 m and 0.2 m/s of
    # the hover, docs/deorbit.md): Q_p 1, R 10, 0.95 of the thrust gave 1.08 x the optimum from the
    # common handover case (the end came 0.8 m low, slowly); Q_p 10, R 1: 0.97 of the thrust 1.042 x,
    # 0.99 1.033 x but 8 infeasible QPs in test_descent_mpc.py (no authority left off the reference).
    position_weight: float = 10.0  # Q on position [1/m^2]
    velocity_weight: float = 4.0  # Q on velocity [1/(m/s)^2]
    acceleration_weight: float = 1.0  # R on acceleration deviation [1/(m/s^2)^2]
    terminal_weight: float = 20.0  # P = terminal_weight * Q
    reference_thrust_fraction: float = 0.97
    reference_steps: int = 60

    def __post_init__(self) -> None:
        if self.horizon_steps < 2 or not (self.step > 0):
            raise GuidanceError(f"horizon_steps must be >= 2 and step > 0, got {self.horizon_steps}, {self.step}")
        if not (0 < self.reference_thrust_fraction <= 1):
            raise GuidanceError(f"reference_thrust_fraction must be in (0, 1], got {self.reference_thrust_fraction}")
        for name in ("position_weight", "velocity_weight", "acceleration_weight", "terminal_weight"):
            if not (getattr(self, name) > 0):
                raise GuidanceError(f"{name} must be positive, got {getattr(self, name)}")


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
        lerp = lambda a: (1 - w) * a[k] + w * a[k + 1]  # noqa: E731 (local one-liner)
        # position and velocity interpolated linearly between nodes: their error is O(dt^2) of the
        # reference's own discretisation, well under what the feedback corrects
        return lerp(s.position_L), lerp(s.velocity_L), lerp(acc)


class DescentMpc:
    """The receding-horizon law; :meth:`command` gives the thrust vector to fly now.

    ``free_horizontal``: the descent ends in a hover at ``target_L``'s altitude wherever the
    fuel-optimal reference ends it (no landing spot), which then is the target.
    """

    def __init__(self, position_L: np.ndarray, velocity_L: np.ndarray, mass: float, gravity: float,
                 limits: DescentLimits, target_L: np.ndarray | None = None,
                 settings: MpcSettings | None = None, free_horizontal: bool = False,
                 drag: DragModel | None = None) -> None:
        import cvxpy as cp

        self.settings = st = settings or MpcSettings()
        self.limits, self.g = limits, float(gravity)
        self.target = np.zeros(3) if target_L is None else np.asarray(target_L, float)
        ref_limits = DescentLimits(rho_max=limits.rho_max * st.reference_thrust_fraction, alpha=limits.alpha,
                                   dry_mass=limits.dry_mass, rho_min=limits.rho_min, max_tilt=limits.max_tilt,
                                   glide_slope=limits.glide_slope)
        # The final time needs no more precision than a control period: fuel is flat near its optimum.
        reference = solve(DescentProblem(position_L=position_L, velocity_L=velocity_L, mass=mass,
                                         gravity=gravity, limits=ref_limits, target_L=self.target,
                                         free_horizontal=free_horizontal, drag=drag),
                          steps=st.reference_steps, t_tol=1e-3)
        if free_horizontal:  # a hover wherever the optimum ends it: that point is the target
            self.target = np.array(reference.position_L[-1])
        self.reference = Reference(reference, gravity, self.target)
        self.drag = drag
        self.stats = MpcStats()
        H, h = st.horizon_steps, st.step
        # exact discretisation of r'' = a + g_L with a held over the step
        self._x0 = cp.Parameter(6)
        self._xref = cp.Parameter((H + 1, 6))
        self._aref = cp.Parameter((H, 3))
        self._amax = cp.Parameter(nonneg=True)
        # drag acceleration over each predicted step, evaluated along the reference (an affine,
        # known term: the reference is drag-consistent, and the feedback takes the difference)
        self._adrag = cp.Parameter((H, 3))
        x = cp.Variable((H + 1, 6))
        a = cp.Variable((H, 3))
        g_L = np.array([0.0, 0.0, -self.g])
        q = np.r_[[st.position_weight] * 3, [st.velocity_weight] * 3]
        cons = [x[0] == self._x0,
                x[1:, :3] == x[:-1, :3] + h * x[:-1, 3:] + (h * h / 2) * (a + self._adrag + np.ones((H, 1)) @ g_L[None, :]),
                x[1:, 3:] == x[:-1, 3:] + h * (a + self._adrag + np.ones((H, 1)) @ g_L[None, :]),
                cp.norm(a, axis=1) <= self._amax,
                a[:, 2] >= math.cos(limits.max_tilt) * cp.norm(a, axis=1),
                x[:, 2] >= 0]
        if limits.glide_slope > 0 and not free_horizontal:
            rel = x[:, :3] - np.ones((H + 1, 1)) @ self.target[None, :]
            # the state at the handover may already be outside the cone: only the predicted steps
            cons.append(cp.norm(rel[1:, :2], axis=1) * math.tan(limits.glide_slope) <= rel[1:, 2])
        dx = x - self._xref
        cost = (cp.sum(cp.multiply(np.ones((H, 1)) @ q[None, :], cp.square(dx[:-1])))
                + st.acceleration_weight * cp.sum_squares(a - self._aref)
                + st.terminal_weight * cp.sum(cp.multiply(q, cp.square(dx[-1]))))
        self._a = a
        self._program = cp.Problem(cp.Minimize(cost), cons)
        self._last = self.reference.at(0.0)[2]

    def command(self, t: float, position_L: np.ndarray, velocity_L: np.ndarray, mass: float) -> np.ndarray:
        """Thrust vector [N, local frame] to hold until the next period; ``t`` s after the handover."""
        import cvxpy as cp

        st = self.settings
        H, h = st.horizon_steps, st.step
        xr = np.empty((H + 1, 6))
        ar = np.empty((H, 3))
        for k in range(H + 1):
            r, v, acc = self.reference.at(t + k * h)
            xr[k, :3], xr[k, 3:] = r, v
            if k < H:
                ar[k] = acc
        self._x0.value = np.r_[position_L, velocity_L]
        self._xref.value, self._aref.value = xr, ar
        if self.drag is None:
            self._adrag.value = np.zeros((H, 3))
        else:
            # along the reference, except the first step: at the measured state
            pos, vel = xr[:H, :3].copy(), xr[:H, 3:].copy()
            pos[0], vel[0] = position_L, velocity_L
            self._adrag.value = self.drag.acceleration(pos, vel, np.full(H, mass))
        self._amax.value = self.limits.rho_max / mass
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # optimal_inaccurate is checked below
                self._program.solve(solver=cp.CLARABEL)
            ok = self._program.status in ("optimal", "optimal_inaccurate") and self._a.value is not None
        except cp.error.SolverError:
            ok = False
        self.stats.solve_times.append(time.perf_counter() - t0)
        if ok:
            self._last = np.array(self._a.value[0])
        else:
            self.stats.failures += 1  # hold the last command: the next period tries again
        return self._last * mass
