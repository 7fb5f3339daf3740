"""From orbit to the ground: the de-orbit mission, its phases flown by composed parts.

Seed 2's last extension ("Extended Mars lander, part 2: control", section 6): de-orbit the lander,
then stabilise the fall into a hover at a fixed altitude, without the built-in attitude stabiliser.
The attitude is always flown by this law (a quaternion attitude law,
:class:`..attitude.QuaternionAttitudeController`'s gains), never by the stabiliser. World frame
``mars`` (planet-centred), SI units throughout.

Phases (:mod:`.phases`, forward only; each change is the controller's ``mode``, which the autopilot
node publishes in ``AutopilotStatus.mode`` and as a ``MODE_CHANGED`` event)::

    deorbit-slew  turn the thrust axis (body +z) retrograde; the burn is planned at the first step
                  (:func:`lander_autopilot.guidance.deorbit.plan`, with the canopy's own limits
                  and the state's navigation error, ``navigation_*_sigma``)
    deorbit-burn  from the planned start: collective throttle with the attitude law's differential
                  on top (attitude priority), until the osculating periapsis is down to the plan's
    coast         throttles off: with no aerodynamic torque on the sphere the attitude drifts at
                  the rate the burn left, which the attitude law damped
    entry         below the top of the atmosphere (200 km). Chute first: thrust axis retrograde,
                  no thrust unless the entry's prediction says the chute could not open within its
                  margin (:class:`.chute.ChuteDecision`); then it brakes at ``burn_throttle``
    parachute     from the descent law's request to deploy the chute: no thrust, thrust axis along
                  the airflow, while the chute brakes harder than the descent law would and until
                  the descent law's braking curve is reached
    powered-descent  once the descent law brakes (leaves its coast mode): the powered-descent part
                  (:mod:`.powered`): the scheduled law (:class:`.descent.DescentToAltitude`,
                  ``deorbit``) or the MPC (:class:`.mpc.MpcDescent`, ``deorbit-mpc``)
    hover         once the fall is stopped within ``hover_band`` of the demand altitude at a climb
                  rate within ``hover_speed``, or anywhere under it: :class:`.hover.HoverCapture`
    landing       on demand (demand altitude 0 while hovering), or once the hover has been held
                  ``land_after_hover`` seconds (:meth:`DeorbitController.hover_held`): the landing
                  law to touchdown, flown on demand altitude 0

The parts: the phase machine (:class:`.phases.PhaseMachine`), the descent law, the hover
capture, the online estimator (:class:`.estimation.OnlineEstimator`), the chute decision
(:class:`.chute.ChuteDecision`) and the powered descent. Each is reached through its public
methods. Everything here is core code (no rclpy): the same object flies in a sweep and in the node.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ...design.altitude import vertical_thrust
from ...design.schedule import schedule_descent_rate
from ...design.translational import local_frame
from ...guidance.deorbit import DeorbitPlan, EntryVehicle, Orbit, plan
from ...guidance.descent_mpc import MpcSettings
from ..attitude import QuaternionAttitudeController
from ..base import (
    REQUEST_DEPLOY_PARACHUTE,
    REQUEST_LANDING_UNREACHABLE,
    Controller,
    ControllerError,
    ControlOutput,
    Demand,
    saturate,
)
from ..calibration import AirFit, ThrustCalibration
from ..combined import mix_with_attitude_priority
from ..landing import LandingController
from ..params import ParamTable
from . import axis_kernel
from .chute import ChuteDecision
from .descent import DescentToAltitude
from .estimation import OnlineEstimator
from .geometry import MIN_SPEED, altitude, climb_rate, mean_of, norm3, thrust_axis_attitude
from .hover import HoverCapture
from .mpc import ATTITUDE_LAG, MpcDescent
from .params import DEORBIT_MPC_PARAMS, DEORBIT_PARAMS, SCHEDULED_ROWS
from .phases import (
    DESCENT_PHASES,
    ORBIT_PHASES,
    Event,
    Phase,
    PhaseLog,
    PhaseMachine,
    burn_due,
    in_atmosphere,
    periapsis_reached,
    settled,
)
from .powered import PoweredDescent, ScheduledDescent

#: [m^2] ``sum 1/2 Cd A`` of the open canopy and the body: the descent law's drag once the chute is out
CHUTE_AND_BODY_DRAG_K = (0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2
                         + 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA)
#: The descent's velocity-loop gain is scheduled over the mass from dry to full and the drag's
#: damping [1/s] from none to twice the open chute's at its terminal speed near the ground (~0.2/s;
#: 1/s covers it), on a 5 x 5 grid.
SCHEDULE_DAMPING_MAX = 1.0
SCHEDULE_POINTS = 5
#: [m] a kilometre, for the phase log's altitudes
KM = 1e3


class DeorbitController(Controller):
    """Orbit to a hover, and to the ground on demand (module docstring). Parameters: the table
    :data:`.params.DEORBIT_PARAMS` (``lander controllers deorbit``)."""

    name: ClassVar[str] = "deorbit"
    PARAMS: ClassVar[ParamTable] = DEORBIT_PARAMS

    def __init__(self, vehicle: Vehicle, **params: object) -> None:
        super().__init__(vehicle)
        self._build(self.PARAMS.resolve(params, self.name), ScheduledDescent())

    def _build(self, p: dict[str, object], powered: PoweredDescent) -> None:
        """The parts from the resolved parameters ``p`` (every row of :data:`DEORBIT_PARAMS`)."""
        vehicle = self.vehicle
        self.hover_band = float(p["hover_band"])  # type: ignore[arg-type]  # checked by its row
        self.hover_speed = float(p["hover_speed"])  # type: ignore[arg-type]
        self.chute_first = bool(p["chute_first"])
        self.chute_margin = float(p["chute_margin"])  # type: ignore[arg-type]
        self.chute_altitude = float(p["chute_altitude"])  # type: ignore[arg-type]
        self.predict_every = float(p["predict_every"])  # type: ignore[arg-type]
        self.brake_in_fitted_air = bool(p["brake_in_fitted_air"])
        self._drag_k = CHUTE_AND_BODY_DRAG_K
        self.descent = DescentToAltitude(vehicle, chute_margin=self.chute_margin, brake_fraction=p["brake_fraction"])
        self.descent.stop_above = self._in_band("stop_above", p["stop_above"])
        self.descent.lag = float(p["braking_lag"])  # type: ignore[arg-type]
        self.descent.settle = float(p["braking_settle"])  # type: ignore[arg-type]
        self.descent.axis_limit = float(p["axis_limit"])  # type: ignore[arg-type]
        self.descent.lag_counts_ceiling = bool(p["lag_counts_ceiling"])
        self.descent.learn_headroom = bool(p["learn_headroom"])
        mass_grid = np.linspace(vehicle.dry_mass, vehicle.dry_mass + vehicle.fuel_capacity, SCHEDULE_POINTS)
        self.descent.rate_schedule = schedule_descent_rate(
            self.descent.law.T_v, mass_grid, np.linspace(0.0, SCHEDULE_DAMPING_MAX, SCHEDULE_POINTS),
            pole=float(p["descent_pole"]))  # type: ignore[arg-type]
        self.hover = HoverCapture(vehicle, attitude_poles=p["hover_attitude_poles"])
        self.hover.band, self.hover.speed = self.hover_band, self.hover_speed
        self.landing = LandingController(vehicle)
        self.slew_time = float(p["slew_time"])  # type: ignore[arg-type]
        hold = p["land_after_hover"]
        self.land_after_hover: float | None = None if hold is None else float(hold)  # type: ignore[arg-type]
        self.burn_throttle = float(p["burn_throttle"])  # type: ignore[arg-type]
        self.navigation_sigma = (float(p["navigation_velocity_sigma"]), float(p["navigation_position_sigma"]))  # type: ignore[arg-type]
        self.attitude = QuaternionAttitudeController(vehicle, poles=p["attitude_poles"], design_fuel=p["design_fuel"])  # type: ignore[arg-type]
        # the burn runs at burn_throttle: the plan's exhaust speed is the same at any throttle.
        # The plan keeps the canopy's own limits (the corridor the vehicle survives); the entry
        # predictor flown before the chute keeps the mission's margin on them.
        self.entry_vehicle = EntryVehicle(axial_thrust=vertical_thrust(vehicle) * self.burn_throttle,
                                          fuel_rate=self.descent.law.mdot_max * self.burn_throttle,
                                          dry_mass=vehicle.dry_mass)
        self.chute_vehicle = dataclasses.replace(self.entry_vehicle,
                                                 chute_max_speed=self.chute_margin * c.PARACHUTE_MAX_SPEED,
                                                 chute_max_drag=self.chute_margin * c.PARACHUTE_MAX_DRAG)
        self.chute = ChuteDecision(vehicle, self.chute_vehicle, self.chute_altitude, self.predict_every, self._drag_k)
        self.estimator = OnlineEstimator(vehicle, self._drag_k)
        self.powered = powered
        self.machine = PhaseMachine()
        axis_kernel.load()  # the thrust axis's compiled attitude, before the flight's first period
        self.reset()

    def _in_band(self, name: str, value: object) -> float:
        """A height [m] over the demand that the powered descent ends at: in ``[0, hover_band)``, since a
        descent ending over the band never hands over to the hover (``ControllerError`` names ``name``)."""
        x = float(value)  # type: ignore[arg-type]  # checked >= 0 by its row
        if x >= self.hover_band:
            raise ControllerError(f"{name}: expected less than hover_band ({self.hover_band} m), got {value!r}")
        return x

    def reset(self) -> None:
        self.attitude.reset()
        for law in (self.descent, self.hover, self.landing):
            law.reset()
        self.machine = PhaseMachine()
        self.plan: DeorbitPlan | None = None
        self._t0: float | None = None
        self._chute_open = False
        self._held_since: float | None = None  # start [s] of the hover held in its band, None: not held
        self._held = 0.0  # [s] how long the hover has been held, at the last period
        self._landing_on_hold = False  # the landing began on the hover held, not on a demand
        self.descent.drag_k = 0.0
        self.chute.reset()
        self.descent.drag_scale = 1.0
        self.estimator.reset()
        self.powered.reset()

    # --- what the parts read (powered.Mission) ---------------------------------------------------

    @property
    def phase(self) -> Phase:
        return self.machine.phase

    @property
    def log(self) -> PhaseLog:
        return self.machine.log

    @property
    def chute_open(self) -> bool:
        """True once the descent law has asked for the chute (the mission then flies its drag)."""
        return self._chute_open

    @property
    def air(self) -> AirFit | None:
        """The air fitted under the chute at the powered descent's start (None before, or no chute)."""
        return self.estimator.air

    @property
    def thrust_calibration(self) -> ThrustCalibration:
        """The thrust per modelled mass measured in the de-orbit burn."""
        return self.estimator.thrust_calibration

    def note(self, t: float, why: str) -> None:
        """Log ``why`` at ``t`` [s] in the phase log without a change of phase."""
        self.machine.note(t, why)

    def diagnostics(self) -> dict[str, float]:
        figures = self.powered.diagnostics()
        if self.land_after_hover is not None:
            # the landing on the hover held flies demand altitude 0 whatever the demand in force says
            figures = {**figures, "land_after_hover": self.land_after_hover, "hover_held": self._held,
                       "landing_on_hold": float(self._landing_on_hold)}
        return figures

    def hover_held(self, t: float, state: StateView, demand: Demand) -> float:
        """How long [s] at ``t`` the hover has been held: the time since the lander last met the
        hover's capture criterion (:func:`.phases.settled`: within ``hover_band`` of the demand at a
        climb rate within ``hover_speed``, or under the band and not falling faster) after failing
        it, or since the hover began; 0 at a period that fails it."""
        if settled(altitude(state) - demand.altitude, climb_rate(state), self.hover_band, self.hover_speed):
            if self._held_since is None:
                self._held_since = t
            self._held = t - self._held_since
        else:
            self._held_since, self._held = None, 0.0
        return self._held

    # --- the mission ----------------------------------------------------------------------------

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        out = self._fly_phases(t, state, demand)
        if self.phase is Phase.POWERED:
            out = self.powered.fly(t, state, demand, self, out)
        return out

    def _fly_phases(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        burning = self.phase is Phase.BURN  # before command(): the burn's last period ends inside it
        # from entry on command() is zeros and changes nothing, and its output is read in orbit only
        out = saturate(self.command(t, state, demand)) if self.phase in ORBIT_PHASES else None
        if burning or self.phase is Phase.BURN:
            assert out is not None
            self.estimator.learn_thrust(t, state, self.descent.law.T_v * mean_of(out.throttles) if self.phase is Phase.BURN else 0.0)
        if self.phase in DESCENT_PHASES:
            self.descent.floor = demand.altitude
            if (self.phase is Phase.ENTRY and self.chute_first and not self._chute_open
                    and self._waits_for_chute(state)):
                return self._before_chute(t, state)
            inner = self.descent.update(t, state, demand)
            if not self._chute_open and any(r.kind == REQUEST_LANDING_UNREACHABLE for r in inner.requests):
                # The law's fuel estimate is drag-free: at the top of the atmosphere, at orbital speed,
                # it asks for more than the tank (103 kg from 200 km) for a descent that reaches the
                # hover with 80 kg. Not reported before the chute is out; re-armed for later.
                inner = dataclasses.replace(inner, requests=tuple(
                    r for r in inner.requests if r.kind != REQUEST_LANDING_UNREACHABLE))
                self.descent.law.rearm_unreachable()
            if any(r.kind == REQUEST_DEPLOY_PARACHUTE for r in inner.requests):
                self._open_chute(t)
            if self.phase in (Phase.ENTRY, Phase.PARACHUTE) and self._waits_for_chute(state):
                # Chute first: no thrust while the chute is still to open or still brakes harder than
                # the descent law's braking limb would; the law's mode goes back to coast, so that the
                # powered descent begins where the law itself first brakes under the open chute.
                self.descent.law.mode = "coast"
                if not self._chute_open:
                    coast = saturate(self._entry_command(t, state))
                else:
                    # under the chute: thrust axis against the velocity, where the canopy (attached
                    # on body +z) pulls it anyway (holding the local vertical fights its torque)
                    coast = self._chute_coast(t, state)
                return ControlOutput(coast.throttles, coast.saturated, coast.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
            if self.phase in (Phase.ENTRY, Phase.PARACHUTE) and inner.mode != "coast":
                self.machine.fire(t, Event.BRAKING, f"braking curve reached at {altitude(state):.0f} m")
                self.estimator.fit_air(state, self.descent)
                if not self.brake_in_fitted_air:
                    self.descent.air = None  # the limb on the scale learnt, in still air
                # the braking limb and the collective's throttle on the thrust the burn measured
                self.descent.law.T_v *= self.thrust_calibration.scale
            elif self.chute_first and self._chute_open and self.phase is Phase.PARACHUTE:
                # Still coasting under the chute: thrust axis along the airflow (as above), not the
                # descent law's upright hold, which fights the canopy's torque while the horizontal
                # speed decays (4.7 kg from scenario 0's orbit). Its mode stays its own.
                coast = self._chute_coast(t, state)
                return ControlOutput(coast.throttles, coast.saturated, coast.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
            if (self.phase is Phase.POWERED and demand.altitude > 0
                    and settled(altitude(state) - demand.altitude, climb_rate(state), self.hover_band, self.hover_speed)):
                self.hover.law.heading_W = self.landing.heading_W = self.descent.law.heading_W  # no yaw turn at the handover
                L = local_frame(state.r_W)
                self.hover.take_over(self.descent.horizontal_drag(L, altitude(state), np.zeros(3)))
                self.machine.fire(t, Event.SETTLED, f"fall stopped within {self.hover_speed:g} m/s at "
                                  f"{altitude(state) - demand.altitude:+.1f} m from the hover")
            else:
                return ControlOutput(inner.throttles, inner.saturated, inner.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
        if self.phase is Phase.HOVER and demand.altitude == 0.0:
            self.machine.fire(t, Event.LAND, "land on demand")
        elif (self.phase is Phase.HOVER and self.land_after_hover is not None
              and self.hover_held(t, state, demand) >= self.land_after_hover):
            self._landing_on_hold = True
            self.machine.fire(t, Event.LAND, f"hover held {self._held:.1f} s (land_after_hover "
                              f"{self.land_after_hover:g} s): land as on demand altitude 0")
        if self.phase is Phase.HOVER:
            inner = self.hover.update(t, state, demand)
        elif self.phase is Phase.LANDING:
            # the landing law flies to the ground: demand altitude 0, whether demanded or on the hover held
            inner = self.landing.update(t, state, dataclasses.replace(demand, altitude=0.0)
                                        if self._landing_on_hold else demand)
        else:
            assert out is not None  # the orbit's phases
            return ControlOutput(out.throttles, out.saturated, out.unclipped, mode=self.phase.value)
        return ControlOutput(inner.throttles, inner.saturated, inner.unclipped, mode=self.phase.value,
                             requests=inner.requests)

    def _open_chute(self, t: float) -> None:
        """The descent law asked for the chute: its drag from now on, and entry ends."""
        self._chute_open = True
        self.descent.drag_k = self._drag_k
        if self.phase is Phase.ENTRY:
            self.machine.fire(t, Event.CHUTE_OPENED, "chute within its limits")

    def _before_chute(self, t: float, state: StateView) -> ControlOutput:
        """Entry, chute first, chute still packed: the entry command (:meth:`_entry_command`) and the
        descent law's chute request alone. Its throttles would not be flown here, so its whole update
        (ground-speed mixing, failure watch: ~0.4 ms, 18,000 times from scenario 0's orbit) is not run
        until the chute is out; it then starts from the chute's instant."""
        self.estimator.learn_density(t, state, self.descent)
        request = self.descent.law.chute_request(altitude(state), climb_rate(state), norm3(state.v_W))
        if request is None:
            u = saturate(self._entry_command(t, state))
            self.estimator.entry_thrust(self.descent.law.T_v * mean_of(u.throttles))
            return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=self.phase.value)
        self._open_chute(t)
        u = saturate(self._retrograde(state, 0.0))
        return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=self.phase.value, requests=(request,))

    def _waits_for_chute(self, state: StateView) -> bool:
        """True while the chute-first descent coasts (:meth:`.chute.ChuteDecision.waits`)."""
        return self.chute_first and self.chute.waits(state, self._chute_open, self.descent)

    def _chute_coast(self, t: float, state: StateView) -> ControlOutput:
        """Under the open chute, no collective: the thrust axis held against the velocity, and the
        drag measured (:meth:`.estimation.OnlineEstimator.learn_drag`)."""
        self.estimator.learn_drag(t, state, self.descent)
        coast = saturate(self._retrograde(state, 0.0))
        # the thrust this period flies [N, world], for the next period's measured drag
        self.estimator.chute_thrust(self.descent.law.T_v * self.thrust_calibration.scale * mean_of(coast.throttles)
                                    * quat_to_matrix(state.q)[2])
        return coast

    def _entry_command(self, t: float, state: StateView) -> np.ndarray:
        """Before the chute: thrust axis retrograde; brake (``burn_throttle``) only while the entry's
        prediction says the chute could not open within its margin (:meth:`.chute.ChuteDecision.entry_brakes`)."""
        brake = self.chute.entry_brakes(t, state)
        retro = -state.v_W / norm3(state.v_W)
        d = self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state)
        return mix_with_attitude_priority(self.burn_throttle if brake else 0.0, d)

    def _retrograde(self, state: StateView, collective: float) -> np.ndarray:
        """Throttles holding the thrust axis against the velocity (attitude priority) [unclipped]."""
        retro = -state.v_W / max(norm3(state.v_W), MIN_SPEED)
        return mix_with_attitude_priority(collective, self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state))

    def start_in(self, phase: Phase, chute_open: bool = False) -> None:
        """Begin the mission at ``phase`` (ENTRY or later) with no de-orbit plan: for flights that
        start from a state inside the atmosphere, e.g. one handover case flown by both descent laws."""
        if phase in ORBIT_PHASES:
            raise ControllerError(f"start_in: the phases before entry need the de-orbit plan, got {phase.value!r}")
        self.reset()
        self.machine = PhaseMachine(phase)
        self._chute_open = bool(chute_open)
        self.descent.drag_k = self._drag_k if chute_open else 0.0
        self.descent.law.assume_chute_requested(self._chute_open)  # the chute is out: the law must not ask again

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        if self.phase not in ORBIT_PHASES:
            return np.zeros(self.n_thrusters)  # from entry on, update() flies the descent laws
        if self.plan is None:
            self._t0 = t
            self.plan = plan(state.r_W, state.v_W, self.vehicle.mass(state.fuel), self.entry_vehicle,
                             slew_time=self.slew_time, min_chute_altitude=self.chute_altitude,
                             velocity_sigma=self.navigation_sigma[0], position_sigma=self.navigation_sigma[1])
        since = t - (self._t0 or 0.0)
        h = altitude(state)
        if self.phase is Phase.SLEW and burn_due(since, self.plan.burn_start):
            self.machine.fire(t, Event.BURN_START, f"planned burn start {self.plan.burn_start:.1f} s")
        if self.phase is Phase.BURN:
            orbit = Orbit.of(state.r_W, state.v_W)
            if periapsis_reached(orbit.periapsis_radius, self.plan.periapsis_altitude):
                self.machine.fire(t, Event.PERIAPSIS, f"periapsis {(orbit.periapsis_radius - c.MARS_RADIUS) / KM:.2f} km")
        if self.phase is Phase.COAST and in_atmosphere(h):
            self.machine.fire(t, Event.ATMOSPHERE, f"altitude {h / KM:.1f} km: top of the atmosphere")
        if self.phase in (Phase.SLEW, Phase.BURN):
            retro = -state.v_W / float(np.linalg.norm(state.v_W))
            d = self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state)
            collective = self.burn_throttle if self.phase is Phase.BURN else 0.0
            return mix_with_attitude_priority(collective, d)
        return np.zeros(self.n_thrusters)


class DeorbitMpcController(DeorbitController):
    """The same mission with the MPC flying the powered descent (:class:`.mpc.MpcDescent`).
    Parameters: the table :data:`.params.DEORBIT_MPC_PARAMS` (``lander controllers deorbit-mpc``).

    The descent law flies the phases before the handover on its braking curve at
    ``handover_fraction`` of the net thrust, ending at the demand itself (``stop_above`` 0: the
    scheduled law's margin would move the handover); the programme's own margin is ``target_above``.
    """

    name: ClassVar[str] = "deorbit-mpc"
    PARAMS: ClassVar[ParamTable] = DEORBIT_MPC_PARAMS

    def __init__(self, vehicle: Vehicle, **params: object) -> None:
        Controller.__init__(self, vehicle)
        p = self.PARAMS.resolve(params, self.name)
        mission = {row.name: row.default for row in SCHEDULED_ROWS}
        mission.update({k: v for k, v in p.items() if k in DEORBIT_PARAMS})
        mission.update(brake_fraction=p["handover_fraction"], stop_above=0.0)
        self.hover_band = float(p["hover_band"])  # type: ignore[arg-type]  # checked by its row
        target_above = self._in_band("target_above", p["target_above"])
        lag = p["attitude_lag"]
        settings = MpcSettings(horizon_steps=p["horizon_steps"], min_time_to_go=p["min_time_to_go"],  # type: ignore[arg-type]
                               reference_steps=p["reference_steps"],  # type: ignore[arg-type]
                               reference_thrust_fraction=p["reference_thrust"],  # type: ignore[arg-type]
                               attitude_lag=ATTITUDE_LAG if lag is None else lag,  # type: ignore[arg-type]
                               plan_reserve=p["plan_reserve"], limb_time=p["limb_time"])  # type: ignore[arg-type]
        part = MpcDescent(vehicle, settings, max_tilt=float(p["max_tilt"]),  # type: ignore[arg-type]
                          glide_slope=float(p["glide_slope"]), target_above=target_above,  # type: ignore[arg-type]
                          coast_collective=float(p["coast_collective"]),  # type: ignore[arg-type]
                          axis_time=float(p["axis_time"]), axis_limit=float(p["axis_limit"]),  # type: ignore[arg-type]
                          stop_within_period=bool(p["stop_within_period"]))
        self.mpc_descent = part
        self._build(mission, part)

    # the MPC's state, read by tests, benches and the sweep's diagnostics
    @property
    def mpc(self) -> object:
        return self.mpc_descent.mpc

    @property
    def settings(self) -> MpcSettings:
        return self.mpc_descent.settings

    @property
    def target_above(self) -> float:
        return self.mpc_descent.target_above

    @property
    def max_tilt(self) -> float:
        return self.mpc_descent.max_tilt

    @property
    def headroom(self) -> object:
        return self.mpc_descent.headroom

    @property
    def thrust_L(self) -> np.ndarray | None:
        return self.mpc_descent.thrust_L

    @property
    def braking_begun(self) -> bool:
        return self.mpc_descent.braking_begun

    @property
    def frame(self) -> np.ndarray | None:
        return self.mpc_descent.frame

