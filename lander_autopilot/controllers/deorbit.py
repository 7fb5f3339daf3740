"""From orbit to the ground: the mission's phases as one small explicit state machine.

Seed 2's last extension (control reference, section 6): de-orbit the lander, then stabilise the fall
into a hover at a fixed altitude, without the built-in attitude stabiliser. The attitude is always
flown by this law (a quaternion attitude law, :class:`.attitude.QuaternionAttitudeController`'s
gains), never by the stabiliser.

Phases (:class:`Phase`, forward only; each change is the controller's ``mode``, which the autopilot
node publishes in ``AutopilotStatus.mode`` and as a ``MODE_CHANGED`` event)::

    deorbit-slew  turn the thrust axis (body +z) retrograde; the burn is planned at the first step
                  (:func:`lander_autopilot.guidance.deorbit.plan`)
    deorbit-burn  from the planned start: collective throttle with the attitude law's differential
                  on top (attitude priority), until the osculating periapsis is down to the plan's
                  (closed loop: the burn ends on the orbit reached, not on a timer)
    coast         throttles off: with no aerodynamic torque on the sphere the attitude drifts at
                  the rate the burn left, which the attitude law damped
    entry         below the top of the atmosphere (200 km): the descent law flies from here (the
                  landing law, :class:`.landing.LandingController`, with its braking profile
                  ending at the demand altitude instead of the ground); attitude held upright,
                  no thrust until its braking curve is reached
    parachute     from the descent law's request to deploy the chute (when its drag and airspeed
                  are within the canopy's limits, with margin)
    powered-descent  once the descent law brakes (leaves its coast mode)
    hover         within ``hover_band`` of the demand altitude and ``hover_speed`` of rest: the
                  ground-speed law (:class:`.ground_speed.GroundSpeedController`) holds the demand
                  altitude and zero ground speed
    landing       on demand (demand altitude 0 while hovering): the landing law to touchdown

Everything here is core code (no rclpy): the same object flies in a sweep and in the node.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import matrix_to_quat, quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.altitude import vertical_thrust
from ..guidance.deorbit import DeorbitPlan, EntryVehicle, Orbit, plan
from ._params import positive_param
from .attitude import QuaternionAttitudeController
from .base import REQUEST_DEPLOY_PARACHUTE, ControlOutput, Controller, Demand, saturate
from .combined import mix_with_attitude_priority
from .ground_speed import GroundSpeedController
from .landing import LandingController


class Phase(str, enum.Enum):
    """Mission phases, in flight order."""

    SLEW = "deorbit-slew"
    BURN = "deorbit-burn"
    COAST = "coast"
    ENTRY = "entry"
    PARACHUTE = "parachute"
    POWERED = "powered-descent"
    HOVER = "hover"
    LANDING = "landing"


#: Phases in which the descent law (landing law ending at the demand altitude) flies.
DESCENT_PHASES = (Phase.ENTRY, Phase.PARACHUTE, Phase.POWERED)


@dataclass
class PhaseLog:
    """Each transition: (time [s], from, to, why)."""

    transitions: list[tuple[float, Phase, Phase, str]]


class DescentToAltitude(LandingController):
    """The landing law with its profile ending at ``floor`` [m] (the demand altitude) instead of the
    ground: the braking and flare limbs are the same curves, lifted by ``floor``."""

    floor: float = 0.0

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        return super().vertical_acceleration(t, h - self.floor, hd, demand)

    def tilt_limit(self, h: float) -> float:
        return super().tilt_limit(h - self.floor)


def thrust_axis_attitude(q: np.ndarray, direction_W: np.ndarray) -> np.ndarray:
    """The attitude (world -> body quaternion) nearest ``q`` with body +z along ``direction_W``.

    The smallest world-frame rotation taking the current body z to the direction, applied to every
    body axis: the yaw about the thrust axis is kept, so the law spends nothing on it.
    """
    R = quat_to_matrix(q)  # rows: body axes in world coordinates
    z = R[2]
    d = np.asarray(direction_W, float) / np.linalg.norm(direction_W)
    axis = np.cross(z, d)
    s, cth = float(np.linalg.norm(axis)), float(z @ d)
    if s < 1e-12:
        if cth > 0:
            return np.array(q, float)
        # opposite: any perpendicular axis does; take body x
        axis, s, cth = R[0], 1.0, -1.0
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    ang = math.atan2(s, cth)
    M = np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * (K @ K)  # Rodrigues
    return matrix_to_quat(R @ M.T)


class DeorbitController(Controller):
    """Orbit to a hover, and to the ground on demand (module docstring). Parameters (SI): ``slew_time``
    [s] before the burn may start, ``burn_throttle`` (collective throttle of the burn, headroom left
    for the attitude law), ``hover_band`` [m] and ``hover_speed`` [m/s] (the powered descent hands
    over to the hover within them), ``attitude_poles`` (of the quaternion attitude law),
    ``design_fuel`` [kg]."""

    name: ClassVar[str] = "deorbit"

    def __init__(self, vehicle: Vehicle, *, slew_time: float = 60.0, burn_throttle: float = 0.85,
                 hover_band: float = 2.0, hover_speed: float = 1.0,
                 attitude_poles: object = (-1.0,) * 6, design_fuel: float | None = None) -> None:
        super().__init__(vehicle)
        self.hover_band = positive_param("hover_band", hover_band)
        self.hover_speed = positive_param("hover_speed", hover_speed)
        self.descent = DescentToAltitude(vehicle)
        self.hover = GroundSpeedController(vehicle)
        self.landing = LandingController(vehicle)
        self.slew_time = positive_param("slew_time", slew_time)
        self.burn_throttle = positive_param("burn_throttle", burn_throttle)
        self.attitude = QuaternionAttitudeController(vehicle, poles=attitude_poles, design_fuel=design_fuel)
        # the burn runs at burn_throttle: the plan's exhaust speed is the same at any throttle
        self.entry_vehicle = EntryVehicle(axial_thrust=vertical_thrust(vehicle) * self.burn_throttle,
                                          fuel_rate=self.descent.mdot_max * self.burn_throttle,
                                          dry_mass=vehicle.dry_mass)
        self.reset()

    def reset(self) -> None:
        self.attitude.reset()
        for law in (self.descent, self.hover, self.landing):
            law.reset()
        self.phase = Phase.SLEW
        self.plan: DeorbitPlan | None = None
        self.log = PhaseLog([])
        self._t0: float | None = None

    def _to(self, t: float, phase: Phase, why: str) -> None:
        self.log.transitions.append((t, self.phase, phase, why))
        self.phase = phase

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        out = saturate(self.command(t, state, demand))
        if self.phase in DESCENT_PHASES:
            self.descent.floor = demand.altitude
            inner = self.descent.update(t, state, demand)
            if self.phase is Phase.ENTRY and any(r.kind == REQUEST_DEPLOY_PARACHUTE for r in inner.requests):
                self._to(t, Phase.PARACHUTE, "chute within its limits")
            if self.phase in (Phase.ENTRY, Phase.PARACHUTE) and inner.mode != "coast":
                self._to(t, Phase.POWERED, f"braking curve reached at {self._altitude(state):.0f} m")
            if self.phase is Phase.POWERED and demand.altitude > 0 and self._settled(state, demand):
                self._to(t, Phase.HOVER, f"within {self.hover_band:g} m and {self.hover_speed:g} m/s of the hover")
            else:
                return ControlOutput(inner.throttles, inner.saturated, inner.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
        if self.phase is Phase.HOVER and demand.altitude == 0.0:
            self._to(t, Phase.LANDING, "land on demand")
        if self.phase is Phase.HOVER:
            inner = self.hover.update(t, state, demand)
        elif self.phase is Phase.LANDING:
            inner = self.landing.update(t, state, demand)
        else:
            return ControlOutput(out.throttles, out.saturated, out.unclipped, mode=self.phase.value)
        return ControlOutput(inner.throttles, inner.saturated, inner.unclipped, mode=self.phase.value,
                             requests=inner.requests)

    @staticmethod
    def _altitude(state: StateView) -> float:
        return float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS

    def _settled(self, state: StateView, demand: Demand) -> bool:
        return (abs(self._altitude(state) - demand.altitude) <= self.hover_band
                and float(np.linalg.norm(state.v_W)) <= self.hover_speed)

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        if self.plan is None:
            self._t0 = t
            self.plan = plan(state.r_W, state.v_W, self.vehicle.mass(state.fuel), self.entry_vehicle,
                             slew_time=self.slew_time)
        since = t - (self._t0 or 0.0)
        altitude = self._altitude(state)
        if self.phase is Phase.SLEW and since >= self.plan.burn_start:
            self._to(t, Phase.BURN, f"planned burn start {self.plan.burn_start:.1f} s")
        if self.phase is Phase.BURN:
            orbit = Orbit.of(state.r_W, state.v_W)
            if orbit.periapsis_radius <= c.MARS_RADIUS + self.plan.periapsis_altitude:
                self._to(t, Phase.COAST, f"periapsis {(orbit.periapsis_radius - c.MARS_RADIUS) / 1e3:.2f} km")
        if self.phase is Phase.COAST and altitude < c.EXOSPHERE_ALTITUDE:
            self._to(t, Phase.ENTRY, f"altitude {altitude / 1e3:.1f} km: top of the atmosphere")
        if self.phase in (Phase.SLEW, Phase.BURN):
            retro = -state.v_W / float(np.linalg.norm(state.v_W))
            d = self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state)
            collective = self.burn_throttle if self.phase is Phase.BURN else 0.0
            return mix_with_attitude_priority(collective, d)
        return np.zeros(self.n_thrusters)

