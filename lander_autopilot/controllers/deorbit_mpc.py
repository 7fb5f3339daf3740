"""``deorbit-mpc``: the de-orbit mission with model predictive control flying the powered descent.

"Extended Mars lander, part 2: control", section 6 (de-orbit, model predictive control). Every
phase is :class:`.deorbit.DeorbitController`'s (slew, burn, coast, entry, parachute, hover,
landing); only ``powered-descent`` differs. At the handover (the instant the scheduled descent law
would start braking under the open chute) this law

1. builds the point-mass problem of the rest of the descent in the local frame of the handover
   point (:func:`handover_problem`: ENU at the handover position, origin on the surface below it,
   z = altitude; thrust, fuel flow and tilt limit of the vehicle, the thrust scaled as measured in
   the de-orbit burn; the open chute's and the body's drag, scaled and in the wind as fitted under
   the chute, :mod:`.calibration`) and
2. flies it with :class:`lander_autopilot.guidance.descent_mpc.DescentMpc`: each control period a
   second-order-cone programme (cvxpy + Clarabel) re-plans the minimum-fuel descent from the measured
   state to rest ``target_above`` (1.5 m) over the demand by the end time of the minimum-fuel reference
   (:func:`lander_autopilot.guidance.fuel_optimal.solve`, lossless convexification with the drag
   re-linearised), within the throttle limit, the tilt limit and a glide slope.

The thrust vector the QP asks for becomes a thrust-axis attitude (the quaternion attitude law,
attitude priority) and a collective throttle ``|T| / T_axial``; once the braking has begun, the
thrust no more than stops the fall within the period (:meth:`DeorbitMpcController._stop_within_period`)
and the axis asked of the attitude law carries integral action on the axis flown against the one
the QP asks for (:meth:`DeorbitMpcController._axis_flown_as_asked`: under the canopy the
proportional-derivative law flies about half the tilt asked for).
The phase ends as the scheduled law's does: within ``hover_band`` m and ``hover_speed`` m/s of the
demand, the ground-speed law holds the hover. Core code (no rclpy); solve times are kept
(:meth:`DeorbitMpcController.diagnostics`).
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.altitude import balanced_thrust, vertical_thrust
from ..design.translational import local_frame
from ..guidance.descent_mpc import DescentMpc, MpcSettings
from ..guidance.fuel_optimal import DescentLimits, DescentProblem, DragModel, GuidanceError, drag_up
from ._params import non_negative_param, positive_param
from .attitude import QuaternionAttitudeController
from .base import ControllerError, ControlOutput, Demand, saturate
from .combined import CollectiveHeadroom, mix_with_attitude_priority
from .deorbit import (
    HOVER_ATTITUDE_POLES,
    AxisIntegral,
    DeorbitController,
    DescentToAltitude,
    Phase,
    axis_slope,
    thrust_axis_attitude,
)

MPC_ATTITUDE_POLE = -2.0  # 1/s: the thrust axis's attitude law in the powered descent (double pole per axis)
# s: the mean delay of that loop, p^2 / (s - p)^2, is 2 / |p|: the lag the QP plans the thrust axis with
ATTITUDE_LAG = 2.0 / abs(MPC_ATTITUDE_POLE)
#: The collective (of the axial thrust) above which the QP's braking has begun: from then on its thrust
#: is capped to what stops the fall within a period (:meth:`DeorbitMpcController._stop_within_period`)
BRAKING_COLLECTIVE = 0.5
#: Before the braking, while the QP asks for less than this collective, the lander coasts under the
#: canopy: no thrust, the thrust axis along the airflow (:meth:`DeorbitMpcController._coast_along_air`)
COAST_COLLECTIVE = 0.2
#: [s] integral time of the braking's correction to the thrust axis asked of the attitude law
#: (:class:`.deorbit.AxisIntegral`, :meth:`DeorbitMpcController._axis_flown_as_asked`); at the scheduled
#: law's 1 s (and a 1 m ``target_above``) the 200 km sweep's case 140 stopped 2.4 m under the demand
#: (1.16 x the optimum)
AXIS_TIME = 2.0


def handover_problem(vehicle: Vehicle, r_W: np.ndarray, v_W: np.ndarray, fuel: float, demand_altitude: float,
                     max_tilt: float = 0.7, chute_open: bool = True,
                     surface_density: float = c.ATMOSPHERE_SURFACE_DENSITY,
                     wind_W: np.ndarray | None = None, drag_scale: float = 1.0,
                     thrust_scale: float = 1.0, balanced: bool = False) -> tuple[DescentProblem, np.ndarray]:
    """The minimum-fuel problem from a handover state to rest at ``demand_altitude`` [m], and its frame.

    Local frame: ENU at ``r_W`` (rows of the returned 3x3 ``L``), origin on the surface below,
    z the altitude; the hover point's horizontal position is free. Thrust: every thruster flat
    out along body z (``T_axial``, the canted layout's axial share); ``alpha = mdot_max / T_axial``.
    Gravity at the handover altitude (uniform over a powered phase of ~1 km). Drag: the sphere's
    and, with ``chute_open``, the parachute's (``1/2 Cd A`` each, exponential atmosphere of
    ``surface_density`` [kg/m^3]: the nominal one, or a dispersed flight's true one for its yardstick;
    ``wind_W`` [m/s, world] a steady wind, none by default; ``drag_scale`` multiplies the modelled
    drag: the flown law's measured / modelled drag under the chute; ``thrust_scale`` multiplies the
    thrust at the same fuel flow: the flown law's measured / modelled thrust acceleration,
    :class:`.calibration.ThrustCalibration`). With ``balanced`` the thrust bound and its fuel flow are
    the most the thrusters give with no torque (:func:`..design.altitude.balanced_thrust`) rather than
    every thruster flat out: the same for the nominal vehicle, less for a dispersed one, whose
    attitude law must cancel the torque of full throttle on all of them.
    """
    L = local_frame(r_W)
    h = float(np.linalg.norm(r_W)) - c.MARS_RADIUS
    axial, mdot = balanced_thrust(vehicle) if balanced else (
        vertical_thrust(vehicle), sum(t.fuel_rate for t in vehicle.thrusters if t.enabled))
    axial *= thrust_scale
    limits = DescentLimits(rho_max=axial, alpha=mdot / axial, dry_mass=vehicle.dry_mass, max_tilt=max_tilt)
    k = 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA
    if chute_open:
        k += 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2
    wind_L = (0.0, 0.0, 0.0) if wind_W is None else tuple(float(x) for x in L @ np.asarray(wind_W, float))
    drag = DragModel(k * drag_scale, surface_density, c.ATMOSPHERE_SCALE_HEIGHT, wind_L)
    r = c.MARS_RADIUS + h
    problem = DescentProblem(position_L=np.array([0.0, 0.0, h]), velocity_L=L @ np.asarray(v_W, float),
                             mass=vehicle.mass(fuel), gravity=c.GM_MARS / (r * r), limits=limits,
                             target_L=np.array([0.0, 0.0, demand_altitude]), free_horizontal=True, drag=drag)
    return problem, L


class DeorbitMpcController(DeorbitController):
    """:class:`.deorbit.DeorbitController` with MPC in the powered descent (module docstring).

    Extra parameters (SI): ``horizon_steps``, ``min_time_to_go`` [s] (shortest horizon), ``max_tilt`` [rad]
    (tilt limit of the thrust in the QP), ``glide_slope`` [rad] (0: none; the hover has no landing
    spot, so it only applies with a target point), ``reference_steps`` (nodes of the reference),
    ``reference_thrust`` (fraction of the thrust the reference is solved at, which fixes the end
    time: 0.94; at 0.99 the dispersed descents ended 3-11 m under the hover, docs/deorbit.md) and
    ``plan_reserve`` (0.04: the share of the QP's thrust bound its plan keeps in hand from 1 s
    ahead on, :class:`.guidance.descent_mpc.MpcSettings`). The QP brakes as late as its bound lets
    it, so a lower reference alone bought nothing: it spent the slack on braking later and rode its
    bound again. Kept in hand, the reserve is there when a gust or the drag model's error leaves
    the fall behind the plan; it must leave the plan some room above the reference (0.99 x 0.96 =
    0.95 against 0.94): with none (0.95 and 0.04) the plan could not meet the reference's end
    time and the replayed flights went to 1.3-1.5 x. Each period the QP's thrust bound is also
    scaled by the collective the attitude law leaves (:class:`.combined.CollectiveHeadroom`,
    learnt in the periods where it binds) and its model takes the thrust measured in the burn
    (:class:`.calibration.ThrustCalibration`) and the drag scale and wind fitted under the chute
    (:class:`.calibration.ChuteDragFit`);
    ``attitude_lag`` [s] (how late the QP expects the thrust axis to follow its command; default
    ``ATTITUDE_LAG``, the mean delay of the thrust axis's attitude loop: planned as instant, the QP's
    late horizontal braking was flown ~1 s behind and the hover began with 0.5-1 m/s of drift);
    ``brake_fraction`` sets the handover: where the descent law's braking curve at that fraction of
    the net thrust is reached (0.5: earlier than the scheduled law's 0.95, so that the plan at
    99 % of the thrust still has room); ``target_above`` [m] (1.5, in ``[0, hover_band)``): the QP
    plans to rest this far over the demand. A plan that falls behind (the attitude law's share of
    the collective learnt only as the braking binds) stops short of its target; planned to the
    demand itself, three dispersed flights of 600 stopped 2.1-2.8 m under it, outside the 2 m band,
    and the hover law's climb back cost 0.13-0.15 of the optimum (docs/deorbit.md, "The MPC's
    target (stop 34)"). 1 m from stop 34 to 39; 1.5 since the braking flies the tilt it asks for
    (:meth:`_axis_flown_as_asked`), which leaves it less vertical thrust than the short tilt did: at
    1 m the 200 km sweep's held-out case 233 then stopped 2.36 m under the demand (1.150 x), at
    1.5 m 1.81 m under it (1.048 x; docs/deorbit.md, "The MPC's thrust axis, flown as asked (stop 40)");
    ``limb_time`` [s] (1.0; 0 turns it off): in the last ``limb_time`` before the reference's end the
    vertical thrust is bounded by the constant deceleration to rest at the plan's target, the
    scheduled law's limb: never more than it, and the limb's once it needs the thrust the plan
    brakes on (:meth:`.guidance.descent_mpc.DescentMpc._last_second`: there the plan is degenerate
    along the vertical and, once its end recedes, brakes late period after period; docs/deorbit.md,
    "The MPC's last second (stop 42)"); the rest are
    :class:`.deorbit.DeorbitController`'s.
    """

    name: ClassVar[str] = "deorbit-mpc"

    @staticmethod
    def _fraction(name: str, value: object) -> float:
        x = positive_param(name, value)
        if x > 1.0:
            raise ControllerError(f"{name}: expected a fraction in (0, 1], got {value!r}")
        return x

    @staticmethod
    def _share(name: str, value: object) -> float:
        x = non_negative_param(name, value)
        if x >= 1.0:
            raise ControllerError(f"{name}: expected a share in [0, 1), got {value!r}")
        return x

    def __init__(self, vehicle: Vehicle, *, horizon_steps: int = 20, min_time_to_go: float = 0.3, max_tilt: float = 0.7,
                 glide_slope: float = 0.0, reference_steps: int = 20, reference_thrust: float = 0.94,
                 attitude_lag: float | None = None, plan_reserve: float = 0.04, target_above: float = 1.5,
                 limb_time: float = 1.0,
                 slew_time: float = 60.0,
                 burn_throttle: float = 0.85, hover_band: float = 2.0, hover_speed: float = 0.2,
                 chute_first: bool = True, chute_margin: float = 0.9, chute_altitude: float = 3000.0,
                 predict_every: float = 1.0, brake_fraction: float = 0.5, attitude_poles: object = (-1.0,) * 6,
                 hover_attitude_poles: object = HOVER_ATTITUDE_POLES, design_fuel: float | None = None) -> None:
        # the parent's parameters spelt out, so that the registry names an unknown one. The handover
        # is where the descent law's braking curve (at brake_fraction) is reached; that curve ends at
        # the demand, not stop_above over it (the scheduled law's margin for its own braking; it would
        # move the MPC's handover). The QP's own margin is target_above.
        super().__init__(vehicle, slew_time=slew_time, burn_throttle=burn_throttle, hover_band=hover_band,
                         hover_speed=hover_speed, chute_first=chute_first, chute_margin=chute_margin,
                         chute_altitude=chute_altitude, predict_every=predict_every, brake_fraction=brake_fraction,
                         stop_above=0.0, attitude_poles=attitude_poles, hover_attitude_poles=hover_attitude_poles,
                         design_fuel=design_fuel)
        if not isinstance(horizon_steps, int) or horizon_steps < 2:
            raise ControllerError(f"horizon_steps: expected an integer >= 2, got {horizon_steps!r}")
        if not isinstance(reference_steps, int) or reference_steps < 10:
            raise ControllerError(f"reference_steps: expected an integer >= 10, got {reference_steps!r}")
        self.max_tilt = positive_param("max_tilt", max_tilt)
        if self.max_tilt > math.pi / 2:
            raise ControllerError(f"max_tilt: expected at most pi/2 rad, got {max_tilt!r}")
        if not (0.0 <= float(glide_slope) < math.pi / 2):
            raise ControllerError(f"glide_slope: expected a value in [0, pi/2) rad, got {glide_slope!r}")
        self.glide_slope = float(glide_slope)
        self.target_above = self._in_band("target_above", target_above)
        self.settings = MpcSettings(horizon_steps=horizon_steps, min_time_to_go=positive_param("min_time_to_go", min_time_to_go),
                                    reference_steps=reference_steps,
                                    reference_thrust_fraction=self._fraction("reference_thrust", reference_thrust),
                                    attitude_lag=ATTITUDE_LAG if attitude_lag is None else non_negative_param("attitude_lag", attitude_lag),
                                    plan_reserve=self._share("plan_reserve", plan_reserve),
                                    limb_time=non_negative_param("limb_time", limb_time))
        self.axial = vertical_thrust(vehicle)
        # the thrust axis is turned faster than the de-orbit slew's (-1): the QP's thrust direction
        # changes within seconds (the ground-speed law's inner loop uses the same -2)
        self.mpc_attitude = QuaternionAttitudeController(vehicle, poles=(MPC_ATTITUDE_POLE,) * 6)

    def reset(self) -> None:
        super().reset()
        if hasattr(self, "mpc_attitude"):
            self.mpc_attitude.reset()
        self.mpc: DescentMpc | None = None
        self._frame: np.ndarray | None = None
        self._origin: np.ndarray | None = None
        self._t_handover = 0.0
        self.reference_time = math.nan  # wall time of the handover's reference solve [s]
        self.thrust_L: np.ndarray | None = None
        self.headroom = CollectiveHeadroom()  # what the attitude law takes of the collective
        self._t_last = math.nan
        self.braking_begun = False  # the QP has asked for over BRAKING_COLLECTIVE of the thrust
        # the braking's integral action on the thrust axis (the scheduled law's limit, ~11 degrees)
        self.axis_integral = AxisIntegral(AXIS_TIME, DescentToAltitude.AXIS_MAX)

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        out = super().update(t, state, demand)
        if self.phase is not Phase.POWERED:
            return out
        if self.mpc is None:
            self._start(t, state, demand)
        if self.mpc is None:  # no feasible reference: the scheduled law flies on (reported in diagnostics)
            return out
        L, r0 = self._frame, self._origin
        assert L is not None and r0 is not None
        h = float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS
        d = L @ (state.r_W - r0)
        p_L = np.array([d[0], d[1], h])
        v_L = L @ state.v_W
        axis_L = L @ quat_to_matrix(state.q)[2]  # the thrust axis flown now
        mass = self.vehicle.mass(state.fuel)
        T_L = self.mpc.command(t - self._t_handover, p_L, v_L, mass, thrust_axis_L=axis_L,
                               available=self.headroom.available)
        if self.braking_begun:
            T_L = self._stop_within_period(T_L, mass, h, v_L, float(axis_L[2]), state.r_W)
        self.thrust_L = T_L  # the QP's thrust this period, capped [N, handover's local ENU frame]
        mag = float(np.linalg.norm(T_L))
        direction_W = L.T @ (T_L / mag) if mag > 1e-6 else state.r_W / float(np.linalg.norm(state.r_W))
        axial = self.axial * self.thrust_calibration.scale  # the axial thrust the burn measured
        collective = mag / axial
        coast = not self.braking_begun and collective < COAST_COLLECTIVE and self._chute_open
        if coast:
            direction_W, collective = self._coast_along_air(state), 0.0
        direction_W = self._axis_flown_as_asked(t, state, L, direction_W)
        diff = self.mpc_attitude.command_toward(thrust_axis_attitude(state.q, direction_W), state)
        top = float(diff.max())
        if t > self._t_last and not coast:  # the headroom is learnt where the collective is flown
            self.headroom.update(top, collective > 1.0 - top, t - self._t_last)
        self._t_last = t
        self.braking_begun = self.braking_begun or collective > BRAKING_COLLECTIVE
        u = saturate(mix_with_attitude_priority(collective, diff))
        return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=self.phase.value, requests=out.requests)

    def _axis_flown_as_asked(self, t: float, state: StateView, L: np.ndarray, direction_W: np.ndarray) -> np.ndarray:
        """The thrust axis to ask of the attitude law [unit, world] for the QP's ``direction_W``: from
        the braking on (the flag as the period began), corrected by integral action on the axis flown
        against the one asked (:class:`.deorbit.AxisIntegral`, ``AXIS_TIME``; ``L`` the handover's
        local frame, rows); before it, ``direction_W`` as it is and the integral paused.

        Why: the attitude law is proportional-derivative, and under the canopy in a wind the canopy's
        torque pulls body +z back toward the airflow, a steady error: the canopy's weathervane
        stiffness (``L/2`` times its drag, ~350 N m/rad at 30 m/s) is about the attitude law's own
        (``I omega^2`` at the pole -2), so the axis flew about half the tilt asked for. The QP's lag
        model (``attitude_lag``) expects the axis to catch up, so the drift was taken out late, at the
        end, in a swing of the axis (200 km case 24: 7.5-10 degrees asked and 4.5 flown through the
        first 2 s of the braking, 22 asked and 11 flown at its end). The scheduled law has had the same
        integral since stop 28 (:meth:`.deorbit.DescentToAltitude.axis_bias`). With it the QP's
        ``target_above`` is 1.5 m (see the class). Replayed on the sweeps' 400 cases and 200 held out,
        held 30 s: 592 -> 596 within 1.05 x (docs/deorbit.md, "The MPC's thrust axis, flown as asked (stop 40)")."""
        if not self.braking_begun:
            self.axis_integral.pause()
            return direction_W
        wanted = axis_slope(L @ direction_W)
        b = self.axis_integral.update(t, state.q, L, wanted)
        axis = np.array([wanted[0] + b[0], wanted[1] + b[1], 1.0])
        return L.T @ (axis / np.linalg.norm(axis))

    def _coast_along_air(self, state: StateView) -> np.ndarray:
        """The thrust axis to hold [unit, world] while the QP, before its braking, asks for little
        thrust (under ``COAST_COLLECTIVE``): against the velocity through the air fitted under the
        chute (:meth:`.deorbit.DeorbitController._fit_air`; still air without a fit), where the
        canopy's torque points the body, with no thrust. Flying the QP's small thrust along its own
        direction held the axis off the airflow against the canopy: the attitude law's differential
        burnt 0.05-0.15 kg over the coast, and the ~1 s the axis then took to turn onto the braking's
        direction was already in the QP's lag model. Replayed from the sweeps' snapshots (stop 38, the
        fuel read at the first control instant in the band, as the stops before): within 1.05 x
        198 -> 199 of 200 (scenario 0's orbit) and 195 -> 197 (200 km), mean 1.0234 -> 1.0227 and
        1.0261 -> 1.0259 (docs/deorbit.md, "The MPC's coast (stop 38)")."""
        wind_W = self.air.wind_W if self.air is not None else np.zeros(3)
        air_W = state.v_W - wind_W
        return -air_W / max(float(np.linalg.norm(air_W)), 1e-9)

    def _stop_within_period(self, T_L: np.ndarray, mass: float, h: float, v_L: np.ndarray, axis_up: float,
                            r_W: np.ndarray) -> np.ndarray:
        """The QP's thrust ``T_L`` [N, local ENU], shortened so that, flown along the thrust axis
        (its up component ``axis_up``), it cannot turn the fall into a climb within one control period.

        While falling (``v_up < 0``), ``|T| <= m (g - a_D,up - v_up / dt) / axis_up`` with ``dt`` the
        period the command is held (``MpcSettings.hold_time``), ``g`` at ``r_W`` and ``a_D,up`` the plan's
        drag (the fitted air) at the altitude ``h`` [m] and velocity ``v_L`` [m/s]; ``axis_up`` is
        floored at 0.5 (a tilted axis does not grow the cap without bound). The scheduled law's
        one-period cap (:meth:`.deorbit.DescentToAltitude.vertical_acceleration`). Why: at the end
        the QP's steps are 15 ms (its last ``min_time_to_go`` over ``H`` steps), and its last braking
        command, held for a whole period, overshot rest into a climb (scenario 0's case 96: 0.8-0.9
        m/s) that was then flown out (docs/deorbit.md, "The MPC's last period (stop 33)"). Replayed
        from the sweeps, held 30 s: within 1.05 x 195 -> 199 of 200 (scenario 0's orbit) and 197 ->
        197 (200 km; within 1.03 x 139 -> 151), no flight worse.
        """
        mpc = self.mpc
        if v_L[2] >= 0.0 or mpc is None:
            return T_L
        g = c.GM_MARS / float(r_W @ r_W)
        a_drag_up = drag_up(mpc.drag, np.array([0.0, 0.0, h]), v_L, mass)
        cap = mass * (g - a_drag_up - float(v_L[2]) / self.settings.hold_time) / max(axis_up, 0.5)
        mag = float(np.linalg.norm(T_L))
        return T_L * (cap / mag) if mag > cap > 0.0 else T_L

    def _start(self, t: float, state: StateView, demand: Demand) -> None:
        import time

        # Under the canopy the lander has drifted with the air: its horizontal velocity is the plan's
        # wind (drag acts on the airspeed; with none, the plan counted on the chute to take the drift
        # out for free and left it to the last second, 4-5 m/s at the hover in a 5 m/s wind).
        up = state.r_W / float(np.linalg.norm(state.r_W))
        wind_W = state.v_W - float(state.v_W @ up) * up if self._chute_open else None
        drag_scale = min(self.descent.drag_scale, 1.0)
        if self.air is not None:
            # the fit over the coast under the chute (DeorbitController._fit_air): the wind's vertical
            # part too, which a scale learnt at the canopy's terminal speed folds in wrongly below it
            wind_W, drag_scale = self.air.wind_W, self.air.scale
        target = demand.altitude + self.target_above  # rest over the demand: a plan that falls behind stops in the band
        problem, L = handover_problem(self.vehicle, state.r_W, state.v_W, state.fuel, target,
                                      max_tilt=self.max_tilt, chute_open=self._chute_open, wind_W=wind_W,
                                      drag_scale=drag_scale, thrust_scale=self.thrust_calibration.scale)
        limits = DescentLimits(rho_max=problem.limits.rho_max, alpha=problem.limits.alpha,
                               dry_mass=problem.limits.dry_mass, max_tilt=self.max_tilt, glide_slope=self.glide_slope)
        t0 = time.perf_counter()
        try:
            self.mpc = DescentMpc(problem.position_L, problem.velocity_L, problem.mass, problem.gravity, limits,
                                  target_L=problem.target_L, settings=self.settings, free_horizontal=True,
                                  drag=problem.drag)
        except GuidanceError as exc:
            self.mpc = None
            self.log.transitions.append((t, self.phase, self.phase, f"MPC refused the handover ({exc}): scheduled law flies"))
        self.reference_time = time.perf_counter() - t0
        self._frame, self._origin, self._t_handover = L, np.array(state.r_W, float), t

    def diagnostics(self) -> dict[str, float]:
        """Solve-time figures of the MPC [s] and counts, for the node's diagnostics (SI units)."""
        if self.mpc is None:
            return {"mpc_solves": 0.0, "mpc_reference_time": self.reference_time}
        st = self.mpc.stats
        return {"mpc_solves": float(len(st.solve_times)), "mpc_failures": float(st.failures),
                "mpc_solve_time_median": st.percentile(50), "mpc_solve_time_p99": st.percentile(99),
                "mpc_solve_time_max": max(st.solve_times) if st.solve_times else math.nan,
                "mpc_solve_time_total": float(sum(st.solve_times)), "mpc_reference_time": self.reference_time}
