"""The MPC powered descent (controller ``deorbit-mpc``): the minimum-fuel descent re-planned each
control period, as a part of the de-orbit mission (:class:`.powered.PoweredDescent`).

"Extended Mars lander, part 2: control", section 6 (de-orbit, model predictive control). Every
other phase is the mission's; at the handover (the instant the scheduled descent law would start
braking under the open chute, on its curve at ``handover_fraction`` of the net thrust) this part

1. builds the point-mass problem of the rest of the descent in the local frame of the handover
   point (:func:`handover_problem`: ENU at the handover position, origin on the surface below it,
   z = altitude; thrust, fuel flow and tilt limit of the vehicle, the thrust scaled as measured in
   the de-orbit burn; the open chute's and the body's drag, scaled and in the wind as fitted under
   the chute, :mod:`..calibration`) and
2. flies it with :class:`lander_autopilot.guidance.descent_mpc.DescentMpc`: each control period a
   second-order-cone programme (cvxpy + Clarabel) re-plans the minimum-fuel descent from the
   measured state to rest ``target_above`` over the demand by the end time of the minimum-fuel
   reference (:func:`lander_autopilot.guidance.fuel_optimal.solve`, lossless convexification with
   the drag re-linearised), within the throttle limit, the tilt limit and a glide slope.

The thrust vector the programme asks for becomes a thrust-axis attitude (the quaternion attitude
law, attitude priority) and a collective throttle ``|T| / T_axial``; once the braking has begun,
the thrust no more than stops the fall within the period (:meth:`MpcDescent.stop_within_period`)
and the axis asked of the attitude law carries integral action on the axis flown against the one
the programme asks for (:meth:`MpcDescent.axis_flown_as_asked`). Before the braking, while the
programme asks for little thrust, the lander coasts along the airflow (:meth:`MpcDescent.coast_along_air`).
Core code (no rclpy); solve times are kept (:meth:`MpcDescent.diagnostics`).
"""
from __future__ import annotations

import math
import time

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ...design.altitude import balanced_thrust, vertical_thrust
from ...design.translational import local_frame
from ...guidance.descent_mpc import DescentMpc, MpcProgramme, MpcSettings
from ...guidance.fuel_optimal import DescentLimits, DescentProblem, DragModel, GuidanceError, drag_up
from ..attitude import QuaternionAttitudeController
from ..base import ControlOutput, Demand, saturate
from ..calibration import AirFit
from ..combined import CollectiveHeadroom, mix_with_attitude_priority
from .geometry import AXIS_LIMIT, AXIS_UP_FLOOR, MIN_SPEED, AxisIntegral, axis_slope, thrust_axis_attitude
from .powered import Mission

MPC_ATTITUDE_POLE = -2.0  # 1/s: the thrust axis's attitude law in the powered descent (double pole per axis)
# s: the mean delay of that loop, p^2 / (s - p)^2, is 2 / |p|: the lag the QP plans the thrust axis with
ATTITUDE_LAG = 2.0 / abs(MPC_ATTITUDE_POLE)
#: The collective (of the axial thrust) above which the programme's braking has begun: from then on
#: its thrust is capped to what stops the fall within a period (:meth:`MpcDescent.stop_within_period`)
#: and the thrust axis carries its integral action. Half the thrust: the coast's small commands
#: (under ``coast_collective``) and the attitude hold's never reach it; every braking does.
BRAKING_COLLECTIVE = 0.5
#: Before the braking, while the programme asks for less than this collective, the lander coasts
#: under the canopy: no thrust, the thrust axis along the airflow (:meth:`MpcDescent.coast_along_air`;
#: the mission's ``coast_collective``). A fifth of the thrust: the handover's first seconds ask
#: for less (the minimum-fuel plan coasts and brakes late), the braking for more than half.
COAST_COLLECTIVE = 0.2
#: [s] integral time of the braking's correction to the thrust axis asked of the attitude law
#: (:class:`.geometry.AxisIntegral`, :meth:`MpcDescent.axis_flown_as_asked`; the mission's
#: ``axis_time``): at the scheduled law's 1 s a windy flight of the 200 km sweep (6.2 m/s of wind)
#: stopped 2.4 m under the demand, outside the hover band.
AXIS_TIME = 2.0
#: [rad] tilt limit of the thrust in the programme (the mission's ``max_tilt``): the ground-speed
#: and landing laws' 40 degrees, which leaves cos 0.7 = 0.76 of the thrust along up
MAX_TILT = 0.7
#: [N] thrust under which the programme's command has no direction worth flying (a coast's zero):
#: the thrust axis is then held up; a micronewton is ~1e-9 of the lander's weight
MIN_THRUST = 1e-6



def handover_problem(vehicle: Vehicle, r_W: np.ndarray, v_W: np.ndarray, fuel: float, demand_altitude: float,
                     max_tilt: float = MAX_TILT, chute_open: bool = True,
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
    wind_L = (0.0, 0.0, 0.0)
    if wind_W is not None:
        w_L = L @ np.asarray(wind_W, float)
        wind_L = (float(w_L[0]), float(w_L[1]), float(w_L[2]))
    drag = DragModel(k * drag_scale, surface_density, c.ATMOSPHERE_SCALE_HEIGHT, wind_L)
    r = c.MARS_RADIUS + h
    problem = DescentProblem(position_L=np.array([0.0, 0.0, h]), velocity_L=L @ np.asarray(v_W, float),
                             mass=vehicle.mass(fuel), gravity=c.GM_MARS / (r * r), limits=limits,
                             target_L=np.array([0.0, 0.0, demand_altitude]), free_horizontal=True, drag=drag)
    return problem, L




class MpcDescent:
    """The powered descent flown by the MPC (module docstring). ``settings`` the programme's
    (:class:`...guidance.descent_mpc.MpcSettings`), ``max_tilt`` [rad] and ``glide_slope`` [rad]
    its limits, ``target_above`` [m] where it plans to rest over the demand; ``coast_collective``,
    ``axis_time``, ``axis_limit`` (0: no integral action on the axis) and ``stop_within_period``
    as the mission's parameters of those names."""

    def __init__(self, vehicle: Vehicle, settings: MpcSettings, *, max_tilt: float, glide_slope: float,
                 target_above: float, coast_collective: float = COAST_COLLECTIVE, axis_time: float = AXIS_TIME,
                 axis_limit: float = AXIS_LIMIT, stop_within_period: bool = True) -> None:
        self.vehicle = vehicle
        self.settings = settings
        self.max_tilt = max_tilt
        self.glide_slope = glide_slope
        self.target_above = target_above
        self.coast_collective = coast_collective
        self.axis_time = axis_time
        self.axis_limit = axis_limit
        self.caps_period = stop_within_period
        self.axial = vertical_thrust(vehicle)
        # the thrust axis is turned faster than the de-orbit slew's (-1): the QP's thrust direction
        # changes within seconds (the ground-speed law's inner loop uses the same -2)
        self.mpc_attitude = QuaternionAttitudeController(vehicle, poles=(MPC_ATTITUDE_POLE,) * 6)
        # the QP, canonicalised here: the handover's period then pays only the reference and one solve
        self.programme = MpcProgramme(settings, max_tilt, glide_slope, free_horizontal=True)
        self.reset()

    def reset(self) -> None:
        self.mpc_attitude.reset()
        self.mpc: DescentMpc | None = None
        self.frame: np.ndarray | None = None  # the handover's local frame (ENU axes in world coordinates, rows)
        self.origin: np.ndarray | None = None  # [m, world] the handover position
        self.t_handover = 0.0
        self.reference_time = math.nan  # wall time of the handover's reference solve [s]
        self.thrust_L: np.ndarray | None = None
        self.headroom = CollectiveHeadroom()  # what the attitude law takes of the collective
        self._t_last = math.nan
        self.braking_begun = False  # the QP has asked for over BRAKING_COLLECTIVE of the thrust
        # the braking's integral action on the thrust axis
        self.axis_integral = AxisIntegral(self.axis_time, self.axis_limit)

    def fly(self, t: float, state: StateView, demand: Demand, mission: Mission,
            scheduled: ControlOutput) -> ControlOutput:
        out = scheduled
        if self.mpc is None:
            self._start(t, state, demand, mission)
        if self.mpc is None:  # no feasible reference: the scheduled law flies on (reported in diagnostics)
            return out
        L, r0 = self.frame, self.origin
        assert L is not None and r0 is not None
        h = float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS
        d = L @ (state.r_W - r0)
        p_L = np.array([d[0], d[1], h])
        v_L = L @ state.v_W
        axis_L = L @ quat_to_matrix(state.q)[2]  # the thrust axis flown now
        mass = self.vehicle.mass(state.fuel)
        T_L = self.mpc.command(t - self.t_handover, p_L, v_L, mass, thrust_axis_L=axis_L,
                               available=self.headroom.available)
        if self.braking_begun and self.caps_period:
            T_L = self.stop_within_period(T_L, mass, h, v_L, float(axis_L[2]), state.r_W)
        self.thrust_L = T_L  # the QP's thrust this period, capped [N, handover's local ENU frame]
        mag = float(np.linalg.norm(T_L))
        direction_W = L.T @ (T_L / mag) if mag > MIN_THRUST else state.r_W / float(np.linalg.norm(state.r_W))
        axial = self.axial * mission.thrust_calibration.scale  # the axial thrust the burn measured
        collective = mag / axial
        coast = not self.braking_begun and collective < self.coast_collective and mission.chute_open
        if coast:
            direction_W, collective = self.coast_along_air(state, mission.air), 0.0
        direction_W = self.axis_flown_as_asked(t, state, L, direction_W)
        diff = self.mpc_attitude.command_toward(thrust_axis_attitude(state.q, direction_W), state)
        top = float(diff.max())
        if t > self._t_last and not coast:  # the headroom is learnt where the collective is flown
            self.headroom.update(top, collective > 1.0 - top, t - self._t_last)
        self._t_last = t
        self.braking_begun = self.braking_begun or collective > BRAKING_COLLECTIVE
        u = saturate(mix_with_attitude_priority(collective, diff))
        return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=mission.phase.value, requests=out.requests)

    def axis_flown_as_asked(self, t: float, state: StateView, L: np.ndarray, direction_W: np.ndarray) -> np.ndarray:
        """The thrust axis to ask of the attitude law [unit, world] for the QP's ``direction_W``: from
        the braking on (the flag as the period began), corrected by integral action on the axis flown
        against the one asked (:class:`.geometry.AxisIntegral`, ``axis_time``, at most ``axis_limit``;
        ``L`` the handover's local frame, rows); before it, or with ``axis_limit`` 0, ``direction_W``
        as it is (the integral paused before the braking).

        Why: the attitude law is proportional-derivative, and under the canopy in a wind the canopy's
        torque pulls body +z back toward the airflow, a steady error: the canopy's weathervane
        stiffness (``L/2`` times its drag, ~350 N m/rad at 30 m/s) is about the attitude law's own
        (``I omega^2`` at the pole -2), so the axis flies about half the tilt asked for. The QP's lag
        model (``attitude_lag``) expects the axis to catch up, so the drift is taken out late, at the
        end, in a swing of the axis (``test_mpc_braking_flies_the_thrust_axis_its_plan_asks_for``)."""
        if self.axis_limit == 0.0:
            return direction_W
        if not self.braking_begun:
            self.axis_integral.pause()
            return direction_W
        wanted = axis_slope(L @ direction_W)
        b = self.axis_integral.update(t, state.q, L, wanted)
        axis = np.array([wanted[0] + b[0], wanted[1] + b[1], 1.0])
        return L.T @ (axis / np.linalg.norm(axis))

    @staticmethod
    def coast_along_air(state: StateView, air: AirFit | None) -> np.ndarray:
        """The thrust axis to hold [unit, world] while the QP, before its braking, asks for little
        thrust (under ``coast_collective``): against the velocity through the air fitted under the
        chute (``air``, :meth:`.estimation.OnlineEstimator.fit_air`; still air without a fit), where
        the canopy's torque points the body, with no thrust. Flying the QP's small thrust along its
        own direction holds the axis off the airflow against the canopy, and the attitude law's
        differential burns fuel over the whole coast
        (``test_mpc_coasts_along_the_airflow_until_its_braking``)."""
        wind_W = air.wind_W if air is not None else np.zeros(3)
        air_W = state.v_W - wind_W
        return -air_W / max(float(np.linalg.norm(air_W)), MIN_SPEED)

    def stop_within_period(self, T_L: np.ndarray, mass: float, h: float, v_L: np.ndarray, axis_up: float,
                           r_W: np.ndarray) -> np.ndarray:
        """The QP's thrust ``T_L`` [N, local ENU], shortened so that, flown along the thrust axis
        (its up component ``axis_up``), it cannot turn the fall into a climb within one control period.

        While falling (``v_up < 0``), ``|T| <= m (g - a_D,up - v_up / dt) / axis_up`` with ``dt`` the
        period the command is held (``MpcSettings.hold_time``), ``g`` at ``r_W`` and ``a_D,up`` the plan's
        drag (the fitted air) at the altitude ``h`` [m] and velocity ``v_L`` [m/s]; ``axis_up`` is
        floored at ``AXIS_UP_FLOOR``. The scheduled law's one-period cap
        (:meth:`.descent.DescentToAltitude.vertical_acceleration`). Why: at the end the QP's steps
        are 15 ms (its last ``min_time_to_go`` over ``H`` steps), and its last braking command, held
        for a whole period, can overshoot rest into a climb that is then flown out
        (``test_mpc_last_braking_period_stops_the_fall_not_into_a_climb``).
        """
        mpc = self.mpc
        if v_L[2] >= 0.0 or mpc is None:
            return T_L
        g = c.GM_MARS / float(r_W @ r_W)
        a_drag_up = drag_up(mpc.drag, np.array([0.0, 0.0, h]), v_L, mass)
        cap = mass * (g - a_drag_up - float(v_L[2]) / self.settings.hold_time) / max(axis_up, AXIS_UP_FLOOR)
        mag = float(np.linalg.norm(T_L))
        return T_L * (cap / mag) if mag > cap > 0.0 else T_L

    def _start(self, t: float, state: StateView, demand: Demand, mission: Mission) -> None:
        # Under the canopy the lander has drifted with the air: its horizontal velocity is the plan's
        # wind (drag acts on the airspeed; with none, the plan counts on the chute to take the drift
        # out for free and leaves it to the last second).
        up = state.r_W / float(np.linalg.norm(state.r_W))
        wind_W = state.v_W - float(state.v_W @ up) * up if mission.chute_open else None
        drag_scale = min(mission.descent.drag_scale, 1.0)
        air = mission.air
        if air is not None:
            # the fit over the coast under the chute: the wind's vertical part too, which a scale
            # learnt at the canopy's terminal speed folds in wrongly below it
            wind_W, drag_scale = air.wind_W, air.scale
        target = demand.altitude + self.target_above  # rest over the demand: a plan that falls behind stops in the band
        problem, L = handover_problem(self.vehicle, state.r_W, state.v_W, state.fuel, target,
                                      max_tilt=self.max_tilt, chute_open=mission.chute_open, wind_W=wind_W,
                                      drag_scale=drag_scale, thrust_scale=mission.thrust_calibration.scale)
        limits = DescentLimits(rho_max=problem.limits.rho_max, alpha=problem.limits.alpha,
                               dry_mass=problem.limits.dry_mass, max_tilt=self.max_tilt, glide_slope=self.glide_slope)
        t0 = time.perf_counter()
        try:
            self.mpc = DescentMpc(problem.position_L, problem.velocity_L, problem.mass, problem.gravity, limits,
                                  target_L=problem.target_L, settings=self.settings, free_horizontal=True,
                                  drag=problem.drag, programme=self.programme)
        except GuidanceError as exc:
            self.mpc = None
            mission.note(t, f"MPC refused the handover ({exc}): scheduled law flies")
        self.reference_time = time.perf_counter() - t0
        self.frame, self.origin, self.t_handover = L, np.array(state.r_W, float), t

    def diagnostics(self) -> dict[str, float]:
        """Solve-time figures of the MPC [s] and counts, for the node's diagnostics (SI units)."""
        if self.mpc is None:
            return {"mpc_solves": 0.0, "mpc_reference_time": self.reference_time}
        st = self.mpc.stats
        return {"mpc_solves": float(len(st.solve_times)), "mpc_failures": float(st.failures),
                "mpc_solve_time_median": st.percentile(50), "mpc_solve_time_p99": st.percentile(99),
                "mpc_solve_time_max": max(st.solve_times) if st.solve_times else math.nan,
                "mpc_solve_time_total": float(sum(st.solve_times)), "mpc_reference_time": self.reference_time}
