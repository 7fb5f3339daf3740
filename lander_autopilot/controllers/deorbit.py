"""From orbit to the ground: the mission's phases as one small explicit state machine.

Seed 2's last extension ("Extended Mars lander, part 2: control", section 6): de-orbit the lander,
then stabilise the fall into a hover at a fixed altitude, without the built-in attitude stabiliser.
The attitude is always flown by this law (a quaternion attitude law,
:class:`.attitude.QuaternionAttitudeController`'s gains), never by the stabiliser. World frame
``mars`` (planet-centred), SI units throughout.

Phases (:class:`Phase`, forward only; each change is the controller's ``mode``, which the autopilot
node publishes in ``AutopilotStatus.mode`` and as a ``MODE_CHANGED`` event)::

    deorbit-slew  turn the thrust axis (body +z) retrograde; the burn is planned at the first step
                  (:func:`lander_autopilot.guidance.deorbit.plan`, with the canopy's own limits)
    deorbit-burn  from the planned start: collective throttle with the attitude law's differential
                  on top (attitude priority), until the osculating periapsis is down to the plan's
                  (closed loop: the burn ends on the orbit reached, not on a timer)
    coast         throttles off: with no aerodynamic torque on the sphere the attitude drifts at
                  the rate the burn left, which the attitude law damped
    entry         below the top of the atmosphere (200 km). Chute first: thrust axis retrograde,
                  no thrust unless a drag-only prediction of the rest of the entry
                  (:func:`.guidance.deorbit.fly_entry`, every ``predict_every`` s) says the chute
                  could not open within ``chute_margin`` of its limits at or above
                  ``chute_altitude``; then it brakes at ``burn_throttle`` until it could
    parachute     from the descent law's request to deploy the chute (drag and airspeed within
                  ``chute_margin`` of the canopy's limits): no thrust, thrust axis along the
                  airflow, while the chute brakes harder than the descent law would and until the
                  descent law's braking curve (with the chute's drag, :class:`DescentToAltitude`)
                  is reached
    powered-descent  once the descent law brakes (leaves its coast mode): the landing law's
                  horizontal and attitude loops with the vertical loop of
                  :class:`DescentToAltitude` (braking limb ending at rest ``stop_above`` over the demand altitude,
                  ``brake_fraction`` of the net thrust the attitude law leaves plus the chute's
                  drag, scheduled gain)
    hover         once the fall is stopped (climb rate within ``hover_speed``) within
                  ``hover_band`` of the demand altitude, or anywhere under it: the ground-speed
                  law holds the demand altitude and zero ground speed, its altitude loop a
                  capture that does not set a lander at rest in the band moving
                  (:class:`HoverCapture`)
    landing       on demand (demand altitude 0 while hovering): the landing law to touchdown

Why chute first: the canopy takes the lander from ~250 m/s to its terminal ~37 m/s for no fuel;
from scenario 0's orbit the earlier law (braking on a drag-blind curve from 8.6 km) used 35 kg in
its powered descent and could not land after 30 s of hover; chute first it uses 12 kg
(docs/deorbit.md, ``bench/deorbit_fuel.py``).

Everything here is core code (no rclpy): the same object flies in a sweep and in the node.
"""
from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.rotation import matrix_to_quat, quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.altitude import vertical_thrust
from ..design.schedule import GainSchedule, schedule_descent_rate
from ..design.translational import local_frame
from ..guidance.deorbit import DeorbitPlan, EntryVehicle, Orbit, fly_entry, plan
from ._params import non_negative_param, poles_param, positive_param
from .attitude import QuaternionAttitudeController
from .base import (
    REQUEST_DEPLOY_PARACHUTE,
    REQUEST_LANDING_UNREACHABLE,
    Controller,
    ControllerError,
    ControlOutput,
    Demand,
    saturate,
)
from .calibration import AirFit, ChuteDragFit, ThrustCalibration
from .combined import CollectiveHeadroom, Mix, mix_with_attitude_priority
from .ground_speed import GroundSpeedController
from .landing import MODES, LandingController


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


def axis_slope(axis_L: np.ndarray) -> np.ndarray:
    """An axis's horizontal over its vertical part, ENU ``(east, north)``, the vertical part floored at
    0.5: how :class:`AxisIntegral` compares the axis flown with the one wanted (both must be measured
    alike)."""
    return axis_L[:2] / max(float(axis_L[2]), 0.5)


class AxisIntegral:
    """Integral action on the thrust axis the attitude law flies, against the one asked of it.

    Under the chute's canopy the attitude law (proportional-derivative) flies the thrust axis short
    of its demand: the canopy's torque pulls body +z back toward the airflow, a steady error. The
    correction added to the axis asked for is ``(1 / time)`` times the integral of ``wanted - flown``
    (each the axis's horizontal over its vertical part, ENU ``(east, north)``), at most ``limit`` in
    norm. For a braking's few seconds only: held on through a 30 s hover it set the horizontal loop
    oscillating (docs/deorbit.md, "The hover's take-over").
    """

    def __init__(self, time: float, limit: float) -> None:
        self.time = time  # [s] integral time
        self.limit = limit  # largest correction (horizontal over vertical part of the axis)
        self.bias = np.zeros(2)  # the correction, ENU (east, north) over up
        self._last: tuple[float, np.ndarray] | None = None  # (t, the axis wanted then)

    def pause(self) -> None:
        """Hold the correction; the next :meth:`update` starts a new interval."""
        self._last = None

    def update(self, t: float, q: np.ndarray, L: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """The correction at time ``t`` [s]: ``q`` the attitude (world -> body), ``L`` the local frame's
        axes in world coordinates (rows), ``wanted`` the axis asked for before the correction."""
        flown = axis_slope(L @ quat_to_matrix(q)[2])
        last = self._last
        if last is not None and t > last[0]:
            self.bias += (t - last[0]) / self.time * (last[1] - flown)
            n = float(np.linalg.norm(self.bias))
            if n > self.limit:
                self.bias *= self.limit / n
        self._last = (t, wanted.copy())
        return self.bias.copy()


def still_air_limb_speed(a_b: float, cd: float, h_c: float) -> float:
    """Fall speed [m/s] from which the braking limb stops in ``h_c`` [m] under thrust deceleration
    ``a_b`` [m/s^2] and a drag ``cd v^2`` in still air (``cd`` [1/m]): ``v^2 = (a_b / cd)(e^{2 cd h_c} - 1)``,
    ``2 a_b h_c`` without drag."""
    return math.sqrt((a_b / cd) * math.expm1(2.0 * cd * h_c)) if cd > 0.0 else math.sqrt(2.0 * a_b * h_c)


#: Gauss-Legendre nodes and weights on [-1, 1] (8 points): the braking limb's height in a wind (FallDrag)
_GAUSS = tuple((float(x), float(w)) for x, w in zip(*np.polynomial.legendre.leggauss(8)))


@dataclass(frozen=True)
class FallDrag:
    """The drag on a fall through moving air, along up, and the braking limb it allows.

    ``cd`` [1/m] is ``s K rho(h) / m`` (the fitted scale, :class:`.calibration.AirFit`); the wind has
    a vertical part ``w_up`` [m/s, up positive] and a horizontal speed ``w_h`` [m/s]. At fall speed
    ``s`` (ground frame, down positive) and no ground speed left, the air meets the lander at
    ``u = s + w_up`` from below and ``w_h`` across: the drag's upward part is
    ``D(s) = cd sqrt(u^2 + w_h^2) u``. The scale learnt at the canopy's terminal speed alone reads
    an updraft as a denser air and scales ``s^2`` with it, so it under-predicts the drag as the fall
    slows (``(s + w)^2 / s^2`` grows): the limb started the braking early and throttled back
    through it.
    """

    cd: float
    w_up: float
    w_h: float

    def deceleration(self, s: float) -> float:
        """``D(s)`` [m/s^2, up], fall speed ``s`` [m/s, down positive]."""
        u = s + self.w_up
        return self.cd * math.sqrt(u * u + self.w_h * self.w_h) * u

    def damping(self, s: float) -> float:
        """``dD/ds`` [1/s]: the drag's damping of the fall speed."""
        u = s + self.w_up
        q = math.sqrt(u * u + self.w_h * self.w_h)
        return self.cd * (q + u * u / q) if q > 0.0 else 0.0

    def stopping_height(self, a_b: float, s: float) -> float:
        """Height [m] a fall at ``s`` [m/s] takes to stop under thrust deceleration ``a_b`` [m/s^2] and
        the drag: ``int_0^s x / (a_b + D(x)) dx`` (density held, as the limb's)."""
        total = 0.0
        for x, w in _GAUSS:
            sig = 0.5 * s * (x + 1.0)
            total += w * sig / (a_b + self.deceleration(sig))
        return 0.5 * s * total

    def limb_speed(self, a_b: float, h_c: float) -> float:
        """Fall speed [m/s] from which the limb stops in ``h_c`` [m]: :meth:`stopping_height` inverted
        by Newton's method from the still-air closed form (``dh/ds = s / (a_b + D(s))``)."""
        v = still_air_limb_speed(a_b, self.cd, h_c)
        if v <= 0.0:  # no thrust to brake with (a_b 0): no limb, as the still-air form's
            return 0.0
        for _ in range(8):
            f = self.stopping_height(a_b, v) - h_c
            v = max(v - f * (a_b + self.deceleration(v)) / v, 1e-6)
            if abs(f) < 1e-6 * max(h_c, 1.0):
                break
        return v


class DescentToAltitude(LandingController):
    """The landing law's vertical loop redesigned to end at rest on ``floor`` [m] (the demand altitude).

    Braking limb: constant thrust deceleration ``a_b`` (``brake_fraction`` of the net thrust
    acceleration at the current mass, on the collective the attitude law leaves: ``headroom``,
    :class:`.combined.CollectiveHeadroom`, learnt while braking; ``T_v`` the thrust the de-orbit
    burn measured, :class:`.calibration.ThrustCalibration`) plus the quadratic drag ``c v^2``, ``c = drag_k rho(h) / m``
    (``drag_k``: ``sum 1/2 Cd A`` of canopy and body [m^2] once the chute is out, else 0; density
    held at the current altitude's over the limb: it only grows below, so the curve is
    conservative). ``d(v^2)/dh = 2 (a_b + c v^2)`` through ``(floor + stop_above, 0)`` gives the descent-rate
    demand ``v_d^2 = (a_b / c)(e^{2 c h_c} - 1)``, ``h_c = h - floor - stop_above`` (``2 a_b h_c`` without drag).
    There is no flare: the limb itself ends at rest in the hover band, as the minimum-fuel descent does
    (full thrust to the last instant); a flare's slow end costs hover thrust, ~7 % of the powered
    fuel a second here. The deceleration asked for is capped at what stops the fall within one
    control period, so the last period does not reverse the speed.

    Once the air is fitted under the chute (:class:`.calibration.AirFit`, at the powered descent's
    start) the drag is the fitted air's on a fall through the fitted wind (:class:`FallDrag`: the
    wind's vertical part moves the airspeed, so the drag no longer scales as ``v^2``), and the limb
    is that ODE's, ``dh/dv = v / (a_b + D(v))``, integrated and inverted each period. With the
    learnt scale alone the fuel grew with the updraft (200 km sweep replayed: median 1.024 in
    downdrafts over 2 m/s, 1.035 in updrafts over 2 m/s; docs/deorbit.md, "The limb in the fitted air").

    Thrust acceleration along up: ``a_U = g + dv_d/dt + c h' |h'| + k(m, d) (T_v / m) (v_d - h')``,
    ``dv_d/dt = (a_b + c v_d^2) h' / v_d`` (chain rule, capped at the limb's own deceleration as
    ``v_d -> 0``): the limb's deceleration fed forward, the drag the air gives taken off (upward while falling),
    and the velocity loop, whose gain ``k`` [throttle per m/s] is **scheduled** over the mass and
    the drag's damping ``d = 2 c |h'|`` (:func:`..design.schedule.schedule_descent_rate`: the pole
    stays at ``descent_pole`` as the air and the tank change the plant). Past the limb's end
    (``h_c <= 0``) it climbs back at ``RETURN_RATE`` per metre, and while still falling there it
    brakes at no less than the limb's ``a_b`` (the one-period cap then ends the fall on the
    control grid). Why: a braking that falls behind its limb (the collective saturated) passes the
    end still falling, and the loop's demand there shrinks with the error: in scenario 0's sweep,
    case 55 crept its last 1.7 m/s out over 0.6 s at 0.7-0.5 of the collective, 0.22 kg (3 % of its
    optimum) more than at ``a_b``. Replayed on the sweeps' 400 flights: 383 -> 393 within 1.05 x
    (docs/deorbit.md, "The braking's end (stop 31)").

    Horizontally, while braking, the ground speed is taken out over the braking left
    (:meth:`horizontal_acceleration`) and the thrust axis the attitude law flies short of its
    demand under the canopy is corrected by integral action (:meth:`axis_bias`).

    Before the fix recorded in docs/deorbit.md the drag term had its sign flipped (drag added to
    the thrust demand instead of taken off): the law braked under the curve and throttled back,
    1.06 x the optimum instead of 1.01 x on the same endpoint.
    """

    floor: float = 0.0
    drag_k: float = 0.0
    drag_scale: float = 1.0  # measured drag / modelled drag under the chute (DeorbitController._learn_drag)
    rate_schedule: GainSchedule | None = None
    RETURN_RATE: ClassVar[float] = 1.0  # [1/s] climb-back demand per metre below the floor
    #: [m] the limb ends this far above the floor, inside the hover band (``DeorbitController.hover_band``,
    #: 2 m): a braking that falls short still stops in the band instead of climbing back to it. The
    #: limb's margin is kept here, in height, more than in thrust (``brake_fraction`` 0.96): a braking
    #: that falls behind its limb ends lower, which costs nothing while it stays in the band; thrust
    #: held back costs every flight a longer burn. 1.0 m with 0.95 until stop 41 (docs/deorbit.md,
    #: "The scheduled law's margin, in height (stop 41)")
    stop_above: float = 1.75
    SETTLE: ClassVar[float] = 0.8  # [s] of the braking left at which the ground speed is to be out
    TAU_MIN: ClassVar[float] = 0.7  # [s] shortest time constant of the horizontal loop (horizontal_acceleration)
    LAG: ClassVar[float] = 0.5  # [s] the attitude's lag to a new tilt under the canopy, braking
    AXIS_TIME: ClassVar[float] = 1.0  # [s] integral time of the thrust axis's correction (axis_bias)
    AXIS_MAX: ClassVar[float] = 0.2  # largest correction, horizontal / vertical part of the axis (~11 deg)
    #: [m/s] horizontal wind (fitted under the chute) from which the headroom also learns at the
    #: mixer's floor (:meth:`mix`); below it only where the ceiling binds
    FLOOR_LEARN_WIND: ClassVar[float] = 4.0
    #: No thruster-failure watch (nor probe burns) on the way down from orbit. The watch's chute
    #: model learns the wind while coasting slowly under the canopy; opened at entry speeds in a
    #: wind, the canopy's unexplained torque (~10 N m per m/s of wind at 40 m/s, growing with the
    #: airspeed squared) looks like a dead thruster within 0.2 s. In the 200 km sweep (200 flights,
    #: no failure drawn) that false alarm switched 7 of the 8 worst replayed flights to the
    #: three-thruster spinning descent: 1.6-2.1 x the optimum's fuel, braking 70-140 m under the hover.
    detects_failures: ClassVar[bool] = False

    def reset(self) -> None:
        super().reset()
        self._time_to_go = 0.0  # [s] braking left on the limb (vertical_acceleration sets it)
        self.headroom = CollectiveHeadroom()  # what the attitude law takes of the collective, braking
        self.air: AirFit | None = None  # the air fitted under the chute (DeorbitController._fit_air)
        self.drift_W = np.zeros(3)  # [m/s, world] horizontal velocity at the braking's start: the wind without a fit
        self.wind_h = 0.0  # [m/s] the horizontal wind at the braking's start (fitted, else the drift)
        self.wind_up = 0.0  # [m/s] the fitted wind's vertical part (up positive)
        self._a_up = 0.0  # [m/s^2] this period's thrust acceleration along up (vertical_acceleration)
        #: [m/s^2] the axial thrust acceleration the mixer gave last period if its ceiling bound
        #: (``T_v mean(u) / m``), else None (:meth:`mix`, :meth:`horizontal_acceleration`)
        self._axial_at_ceiling: float | None = None
        self.axis_integral = AxisIntegral(self.AXIS_TIME, self.AXIS_MAX)  # axis_bias's, braking

    @property
    def wind_W(self) -> np.ndarray:
        """The wind the braking plans on [m/s, world]: the fit under the chute, else the drift."""
        return self.drift_W if self.air is None else self.air.wind_W

    def braking_acceleration(self, mass: float, g: float) -> float:
        """The limb's ``a_b`` on the collective the attitude law leaves (:class:`.combined.CollectiveHeadroom`)."""
        return self.brake_fraction * max(self.headroom.available * self.T_v / mass - g, 0.0)

    def mix(self, t: float, state: StateView, inner: Demand) -> Mix:
        m = super().mix(t, state, inner)
        if self.mode != "coast":
            u = m.throttles if m.mixed_from is None else m.mixed_from
            top = float(u.max())
            # Learn where the ceiling binds; in a strong wind also where the mixer gave way at the
            # floor (as the braking begins, the thrust axis turning against the canopy): there the
            # attitude law's differential through the braking is large, and learnt only once the
            # ceiling binds it comes too late (200 km sweep, winds over 4.3 m/s: 1.15-1.40 x the
            # optimum). In lighter winds the floor's one period taught a share of ~0.03 that the
            # braking never needed, ~1 % of fuel on the typical flight (docs/deorbit.md).
            at_floor = self.wind_h >= self.FLOOR_LEARN_WIND and m.mixed_from is not None
            self.headroom.update(top - self.collective.level, at_floor or top >= 1.0, self._dt)
        self._axial_at_ceiling = self.axial_at_ceiling(m)
        return m

    def axial_at_ceiling(self, m: Mix) -> float | None:
        """Braking: the axial thrust acceleration [m/s^2] the mix ``m`` gives where its ceiling binds,
        ``T_v mean(u) / m`` (``u`` clipped to [0, 1]); None where it does not, and in the coast."""
        if self.mode == "coast" or float(m.throttles.max()) < 1.0:
            return None
        return self.T_v * float(np.clip(m.throttles, 0.0, 1.0).mean()) / self._mass

    def rate_gain(self, damping: float) -> float:
        """Velocity-loop acceleration gain [1/s] at the current mass and drag damping ``d`` [1/s]."""
        if self.rate_schedule is None:
            return self.k_v
        k = float(self.rate_schedule.gain((self._mass, damping))[0, 0])
        return k * self.T_v / self._mass

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        a_b = self.braking_acceleration(self._mass, g)
        h_c = h - self.floor - self.stop_above
        air = self.air
        if air is None or self.drag_k <= 0.0:
            # no fit (chute packed, or a flight begun under it): the scale learnt, still air
            cd = self.drag_k * self.drag_scale * MARS_ATMOSPHERE.density(h) / self._mass
            if h_c > 0.0:
                v = still_air_limb_speed(a_b, cd, h_c)
                limb = a_b + cd * v * v  # the limb's deceleration at v
            drag_up, damping = -cd * hd * abs(hd), 2.0 * cd * abs(hd)
        else:
            wind = FallDrag(self.drag_k * air.scale * MARS_ATMOSPHERE.density(h) / self._mass, self.wind_up, self.wind_h)
            if h_c > 0.0:
                v = wind.limb_speed(a_b, h_c)
                limb = a_b + wind.deceleration(v)
            drag_up, damping = wind.deceleration(-hd), wind.damping(-hd)
        if h_c > 0.0:
            # dv_d/dt = (dv_d/dh) h' = (a_b + D(v)) h' / v_d: the limb's deceleration scaled by how
            # fast the lander closes on it (capped at the limb's own, so it stays finite as v_d -> 0)
            v_d, accel_d = -v, limb * min(max(-hd, 0.0) / v, 1.0) if v > 0.0 else 0.0
            self._time_to_go = v / limb if v > 0.0 else 0.0
        else:
            v_d, accel_d = -self.RETURN_RATE * h_c, 0.0
            self._time_to_go = 0.0
        a_up = g + accel_d - drag_up + self.rate_gain(damping) * (v_d - hd)
        if hd < 0.0:
            if h_c <= 0.0:
                a_up = max(a_up, g - drag_up + a_b)
            a_up = min(a_up, g - drag_up - hd / self._dt)
        if a_up >= 0.1 * g and self.mode == "coast":
            self.mode = MODES[1]
        self._a_up = a_up
        return a_up

    def horizontal_acceleration(self, state: StateView, L: np.ndarray, h: float, v_L: np.ndarray,
                                error: np.ndarray) -> np.ndarray:
        """Braking: the ground speed nulled over the braking left, with the drag fed forward and the
        attitude's lag allowed for (before it, and to a floor of 0, the ground-speed law's PI).

        ``a_h = -(e + LAG a_flown) / tau - a_D``, ENU [m/s^2]: ``e`` the horizontal velocity error,
        ``tau = max(t_go - SETTLE, TAU_MIN)`` (``t_go``: the braking left on the limb at its present
        deceleration, an underestimate, so the speed is out ``SETTLE`` s before it), ``a_D`` the
        drag's horizontal part, ``-s K rho |v - w| (v - w)`` with the air fitted over the coast under
        the chute (:class:`.calibration.AirFit`: scale ``s`` and the wind ``w``, vertical part
        included; without a fit the drag scale learnt and the drift as the wind), and ``a_flown`` the
        horizontal acceleration the thrust axis flies now (thrust along the current body z) plus
        ``a_D``: the attitude reaches a new tilt ~``LAG`` s after it is asked for, and the speed
        that lag still takes out is not asked for twice. The thrust in ``a_flown`` is the one asked
        for (``a_U`` along up), or, where the mixer's ceiling bound last period, no more than the
        one it gave (``T_v mean(u) / m`` along the axis). Why: in a strong wind the braking rides
        the ceiling (the attitude law's share on top of the collective), the thrust flown falls
        10-30 % under the one asked for, and the lag term counted that missing thrust's horizontal
        part as speed already being taken out: the 200 km sweep's cases 24 and 140 (4.3 and 6.2 m/s
        of wind) flew 0.6-0.9 m/s^2 where 1.1-1.4 was asked and began the hover with 0.25-0.29 m/s
        of drift, 1.091 and 1.080 x the optimum; with the thrust flown, 1.044 and 1.032. Replayed on
        the sweeps' 400 flights and 200 held out, held 30 s: 597 -> 598 within 1.05 x
        (docs/deorbit.md, "The thrust the lag term counts (stop 35)").

        Why: the earlier law (the PI with its acceleration capped at ``2 |v_h| / t_go``) left
        0.2-0.5 m/s of drift at the hover, ~1 s of hover thrust (~5-8 % of the optimum's fuel) to
        take out. The integral is held at 0 (it had wound up on the drift while coasting). Alone
        this law gained little (200 km sweep replayed: 108 flights within 1.05 x against 101):
        under the canopy the attitude law flew about half the tilt asked for; with
        :meth:`axis_bias` it does (docs/deorbit.md, "The scheduled law's tail, third pass").

        ``LAG`` 0.5 s and ``SETTLE`` 0.8 s (were 0.7 and 1.5, stop 28): with the fall past the limb's
        end braked at ``a_b`` the braking is shorter, and at 0.7 the lag term held the loop's
        effective time constant near ``tau + LAG``, 1.4 s at the end: the windiest flights began
        the hover with 0.3-0.5 m/s of drift to fly out on hover thrust. Replayed on the sweeps'
        400 flights, held 30 s: 393 -> 398 within 1.05 x; on 200 flights not used to choose them
        (cases 200-299 of each scene): 97 -> 99 (200 km) and 100 -> 100 (scenario 0, mean 1.0272 ->
        1.0266); every pair tried in 0.45-0.55 s and 0.6-1.2 s gave 397-398 (docs/deorbit.md, "The
        braking's end (stop 31)").
        """
        if self.floor <= 0.0 or self.mode == "coast":
            return super().horizontal_acceleration(state, L, h, v_L, error)
        self._integral[:] = 0.0
        drag = self.horizontal_drag(L, h, v_L)
        z_L = L @ quat_to_matrix(state.q)[2]  # the thrust axis flown, ENU
        axial = self._a_up / max(float(z_L[2]), 0.5)
        if self._axial_at_ceiling is not None:
            axial = min(axial, self._axial_at_ceiling)
        flown = axial * z_L[:2] + drag
        tau = max(self._time_to_go - self.SETTLE, self.TAU_MIN)
        return -(error + self.LAG * flown) / tau - drag

    def horizontal_drag(self, L: np.ndarray, h: float, v_L: np.ndarray) -> np.ndarray:
        """The drag's horizontal acceleration, ENU ``(east, north)`` [m/s^2], at altitude ``h`` [m] and
        ENU velocity ``v_L`` [m/s] (``L``: the local frame's axes in world coordinates, rows):
        ``-s K rho |v - w| (v - w)`` with the air fitted under the chute (:meth:`horizontal_acceleration`);
        zero while the chute is packed (``drag_k`` 0)."""
        if self.drag_k <= 0.0:
            return np.zeros(2)
        air = self.air
        scale = self.drag_scale if air is None else air.scale
        rel = v_L - L @ self.wind_W
        cd = self.drag_k * scale * MARS_ATMOSPHERE.density(h) / self._mass
        return -cd * float(np.linalg.norm(rel)) * rel[:2]

    def axis_bias(self, t: float, state: StateView, L: np.ndarray, wanted: np.ndarray) -> np.ndarray | None:
        """Braking: integral action on the thrust axis the attitude law flies against the one wanted
        (:class:`AxisIntegral`); none outside the braking.

        Under the canopy the attitude law (proportional-derivative) flies the thrust axis short of
        its demand: the canopy's torque pulls body +z back toward the airflow. Replayed (200 km
        sweep's case 38, 2.5 m/s of drift to take out) the axis flew under half the tilt asked for
        through the braking, and 0.36 m/s of drift was left at the hover, 1.3 s of hover thrust
        (12 % of the optimum's fuel) to take out.
        """
        if self.floor <= 0.0 or self.mode == "coast":
            self.axis_integral.pause()
            return None
        return self.axis_integral.update(t, state.q, L, wanted)

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray:
        # From the braking on, the heading is the one the body had as it began (``heading_W``, world
        # frame; the hover and the landing keep it). The canopy leaves the body x anywhere; turning it
        # back to east as the braking started (0.9 rad/s of yaw from the canted thrusters'
        # differential throttle) took half of two thrusters for ~2 s of the braking, and the fall ran
        # under the hover. A heading free at every instant (the current body x) cost 1.5 % of the
        # nominal fuel: the yaw rate was never brought to rest.
        if self.mode == "coast":
            self.heading_W = None
        elif self.heading_W is None:
            self.heading_W = quat_to_matrix(state.q)[0].copy()
        return super().heading_axis(state, L)

    def tilt_limit(self, h: float) -> float:
        # the floor is a hover, not a touchdown: the full tilt stays, so the ground speed the chute
        # drifted with in the wind is taken out (the landing law shrinks it to stand upright)
        return self.max_tilt if self.floor > 0.0 else super().tilt_limit(h)


#: The hover's attitude poles [1/s]: twice the ground-speed law's -2 (eight times its velocity loop's
#: -0.5). Under the canopy in a wind the hover takes over with the thrust axis short of the tilt the
#: drag at rest needs; at -2 the 200 km sweep's case 164 flew 0.016 -> 0.05 of the 0.09 asked for in
#: 1.8 s of hover thrust (docs/deorbit.md, "The hover's attitude"). -4 is 0.4 rad per 0.1 s period.
HOVER_ATTITUDE_POLES: tuple[float, ...] = (-4.0,) * 6


class HoverCapture(GroundSpeedController):
    """The hover after the powered descent: the ground-speed law, its altitude loop a capture.

    The fall is stopped within the band ``band`` [m] of the demand (or under it), at rest or
    nearly; the mission counts the powered fuel until the lander is within the band at a total speed
    under ``speed`` [m/s]. The ground-speed law's own altitude loop (eq 18, poles -0.9, -1.1) closes
    a 1 m error at up to 0.5 m/s: a lander already at rest in the band was set moving again and
    came to rest only at the demand, 1.5-2.5 s of hover thrust (~5 % of the optimum's fuel a
    second) in the 200 km sweep. Here the climb-rate demand is ``-k e`` (``e`` the altitude error)
    capped inside the band at ``APPROACH * speed`` and at what the ground speed ``v_h`` leaves of
    ``AT_REST * speed``, ``sqrt((AT_REST speed)^2 - v_h^2)`` (0 once the drift alone is that fast:
    a descent at 0.1 m/s with 0.19 m/s of drift kept the lander out of the band's speed), and outside
    it by a braking curve of deceleration ``CAPTURE_ACCEL`` ending at the band's edge at that speed;
    the thrust acceleration along up is ``g + RATE_GAIN (v_d - h')``.

    The horizontal loop is the ground-speed law's, its integral preset at the handover to hold
    against the drag at rest in the wind fitted under the chute (:meth:`take_over`). Started from
    zero, the wind set the lander drifting faster as the hover began (200 km sweep's case 161:
    0.17 -> 0.24 m/s over 1.5 s), 3.3 s of hover thrust to the band at rest. The braking's integral
    action on the thrust axis (:meth:`DescentToAltitude.axis_bias`) is not carried on here: over
    the 30 s hold it set the horizontal loop oscillating, growing, and 13 of the 200 km sweep's
    200 flights fell from the hover (docs/deorbit.md, "The hover's take-over"). Its attitude law is
    faster than the ground-speed law's (:data:`HOVER_ATTITUDE_POLES`, set by the mission): the tilt
    the wind needs at rest is flown before the drift the braking left can grow.
    """

    band: float = 2.0
    speed: float = 0.2
    APPROACH: ClassVar[float] = 0.5  # of ``speed``: the climb rate allowed inside the band
    POSITION_GAIN: ClassVar[float] = 0.5  # [1/s] climb-rate demand per metre of error
    CAPTURE_ACCEL: ClassVar[float] = 1.0  # [m/s^2] braking into the band from outside it
    RATE_GAIN: ClassVar[float] = 2.0  # [1/s] thrust acceleration per m/s of climb-rate error
    AT_REST: ClassVar[float] = 0.8  # of ``speed``: the total speed the approach inside the band keeps under

    def take_over(self, drag: np.ndarray) -> None:
        """Start from the braking's end with the horizontal loop's integral preset to hold against
        ``drag`` (the drag's horizontal acceleration at rest, ENU [m/s^2]): the tilt the wind needs
        is asked for at once."""
        self._integral[:] = np.asarray(drag, float) / self.k_i

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        e = h - demand.altitude
        # inside the band the climb rate allowed leaves room for the ground speed under ``speed``
        v_h = math.hypot(float(self.v_local[0]), float(self.v_local[1]))
        v_in = min(self.APPROACH * self.speed, math.sqrt(max((self.AT_REST * self.speed) ** 2 - v_h * v_h, 0.0)))
        outside = abs(e) - self.band
        cap = v_in if outside <= 0.0 else math.sqrt(v_in * v_in + 2.0 * self.CAPTURE_ACCEL * outside)
        v_d = -math.copysign(min(self.POSITION_GAIN * abs(e), cap), e)
        r = c.MARS_RADIUS + h
        return c.GM_MARS / (r * r) + self.RATE_GAIN * (v_d - hd)


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
    over to the hover within them), ``chute_first`` (coast for the chute, module docstring),
    ``chute_margin`` (fraction of the canopy's speed and drag limits the chute is opened within),
    ``chute_altitude`` [m] (lowest planned and predicted opening), ``predict_every`` [s] (entry
    prediction period), ``brake_fraction`` (of the net thrust acceleration, the descent law's braking
    limb: 0.96 leaves the feedback 4 % for a thrust, mass or density off the model), ``stop_above``
    [m] (where the limb ends over the demand altitude, in ``[0, hover_band)``: the rest of the limb's
    margin, in height, :attr:`DescentToAltitude.stop_above`), ``descent_pole``
    [1/s] (of its scheduled velocity loop, :class:`DescentToAltitude`), ``attitude_poles`` (of the
    quaternion attitude law), ``hover_attitude_poles`` (the hover's, :class:`HoverCapture`),
    ``design_fuel`` [kg]."""

    name: ClassVar[str] = "deorbit"

    def __init__(self, vehicle: Vehicle, *, slew_time: float = 60.0, burn_throttle: float = 0.85,
                 hover_band: float = 2.0, hover_speed: float = 0.2, chute_first: bool = True,
                 chute_margin: float = 0.9, chute_altitude: float = 3000.0, predict_every: float = 1.0,
                 brake_fraction: float = 0.96, stop_above: float = DescentToAltitude.stop_above,
                 descent_pole: float = -2.0,
                 attitude_poles: object = (-1.0,) * 6, hover_attitude_poles: object = HOVER_ATTITUDE_POLES,
                 design_fuel: float | None = None) -> None:
        super().__init__(vehicle)
        # checked here, so that a bad value is named by its key (the laws' own check says "poles")
        poles_param("attitude_poles", attitude_poles, 6)
        poles_param("hover_attitude_poles", hover_attitude_poles, 6)
        self.hover_band = positive_param("hover_band", hover_band)
        self.hover_speed = positive_param("hover_speed", hover_speed)
        if not isinstance(chute_first, (bool, np.bool_)):
            raise ControllerError(f"chute_first: expected true or false, got {chute_first!r}")
        self.chute_first = bool(chute_first)
        self.chute_margin = positive_param("chute_margin", chute_margin)
        if self.chute_margin > 1.0:
            raise ControllerError(f"chute_margin: expected a fraction in (0, 1], got {chute_margin!r}")
        self.chute_altitude = positive_param("chute_altitude", chute_altitude)
        self.predict_every = positive_param("predict_every", predict_every)
        # canopy and body, 1/2 Cd A [m^2]: the descent law's drag once the chute is out
        self._drag_k = (0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2
                        + 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA)
        self.descent = DescentToAltitude(vehicle, chute_margin=self.chute_margin, brake_fraction=brake_fraction)
        self.descent.stop_above = self._in_band("stop_above", stop_above)
        if not (isinstance(descent_pole, (int, float)) and descent_pole < 0):
            raise ControllerError(f"descent_pole: expected a negative number [1/s], got {descent_pole!r}")
        # the velocity loop's gain over the descent: mass from dry to full, drag damping from none to
        # twice the open chute's at its terminal speed near the ground (~0.2/s; 1/s covers it)
        self.descent.rate_schedule = schedule_descent_rate(
            self.descent.T_v, np.linspace(vehicle.dry_mass, vehicle.dry_mass + vehicle.fuel_capacity, 5),
            np.linspace(0.0, 1.0, 5), pole=float(descent_pole))
        self.hover = HoverCapture(vehicle, attitude_poles=hover_attitude_poles)
        self.hover.band, self.hover.speed = self.hover_band, self.hover_speed
        self.landing = LandingController(vehicle)
        self.slew_time = positive_param("slew_time", slew_time)
        self.burn_throttle = positive_param("burn_throttle", burn_throttle)
        self.attitude = QuaternionAttitudeController(vehicle, poles=attitude_poles, design_fuel=design_fuel)
        # the burn runs at burn_throttle: the plan's exhaust speed is the same at any throttle
        # The plan keeps the canopy's own limits (the corridor the vehicle survives); the entry
        # predictor flown before the chute (_entry_command) keeps the descent law's margin on them.
        self.entry_vehicle = EntryVehicle(axial_thrust=vertical_thrust(vehicle) * self.burn_throttle,
                                          fuel_rate=self.descent.mdot_max * self.burn_throttle,
                                          dry_mass=vehicle.dry_mass)
        self.chute_vehicle = dataclasses.replace(self.entry_vehicle,
                                                 chute_max_speed=self.chute_margin * c.PARACHUTE_MAX_SPEED,
                                                 chute_max_drag=self.chute_margin * c.PARACHUTE_MAX_DRAG)
        self.reset()

    def _in_band(self, name: str, value: object) -> float:
        """A height [m] over the demand that the powered descent ends at: in ``[0, hover_band)``, since a
        descent ending over the band never hands over to the hover (``ControllerError`` names ``name``)."""
        x = non_negative_param(name, value)
        if x >= self.hover_band:
            raise ControllerError(f"{name}: expected less than hover_band ({self.hover_band} m), got {value!r}")
        return x

    def reset(self) -> None:
        self.attitude.reset()
        for law in (self.descent, self.hover, self.landing):
            law.reset()
        self.phase = Phase.SLEW
        self.plan: DeorbitPlan | None = None
        self.log = PhaseLog([])
        self._t0: float | None = None
        self._chute_open = False
        self.descent.drag_k = 0.0
        self._predicted_at = -math.inf
        self._entry_brake = False
        self.descent.drag_scale = 1.0
        self._last_climb: tuple[float, float] | None = None
        self._last_coast: tuple[float, np.ndarray] | None = None  # (t, v_W) at the last entry period
        self._coast_thrust = math.inf  # axial thrust [N] commanded over the period since
        self.thrust_calibration = ThrustCalibration()
        self.air_fit = ChuteDragFit()
        self.air: AirFit | None = None  # the fit at the powered descent's start (_fit_air)
        self._last_air: tuple[float, np.ndarray, np.ndarray, float] | None = None  # (t, v_W, r_W, fuel)
        self._coast_thrust_W = np.zeros(3)  # thrust [N, world] commanded over the period since
        self._last_burn: tuple[float, np.ndarray, np.ndarray, float, float] | None = None  # (t, v_W, g_W, fuel, thrust)

    def _to(self, t: float, phase: Phase, why: str) -> None:
        self.log.transitions.append((t, self.phase, phase, why))
        self.phase = phase

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        burning = self.phase is Phase.BURN  # before command(): the burn's last period ends inside it
        out = saturate(self.command(t, state, demand))
        if burning or self.phase is Phase.BURN:
            self._learn_thrust(t, state, self.descent.T_v * float(np.mean(out.throttles)) if self.phase is Phase.BURN else 0.0)
        if self.phase in DESCENT_PHASES:
            self.descent.floor = demand.altitude
            if (self.phase is Phase.ENTRY and self.chute_first and not self._chute_open
                    and self._waits_for_chute(state, demand)):
                return self._before_chute(t, state)
            inner = self.descent.update(t, state, demand)
            if not self._chute_open and any(r.kind == REQUEST_LANDING_UNREACHABLE for r in inner.requests):
                # The law's fuel estimate is drag-free: at the top of the atmosphere, at orbital speed,
                # it asked for more than the tank (103 kg from 200 km) for a descent that reached the
                # hover with 80 kg. Not reported before the chute is out; re-armed for later.
                inner = dataclasses.replace(inner, requests=tuple(
                    r for r in inner.requests if r.kind != REQUEST_LANDING_UNREACHABLE))
                self.descent._unreachable_raised = False
            if any(r.kind == REQUEST_DEPLOY_PARACHUTE for r in inner.requests):
                self._open_chute(t)
            if self.phase in (Phase.ENTRY, Phase.PARACHUTE) and self._waits_for_chute(state, demand):
                # Chute first: no thrust while the chute is still to open or still brakes harder than
                # the descent law's braking limb would; the law's mode goes back to coast, so that the
                # powered descent begins where the law itself first brakes under the open chute.
                self.descent.mode = "coast"
                if not self._chute_open:
                    coast = saturate(self._entry_command(t, state))
                else:
                    # under the chute: thrust axis against the velocity, where the canopy (attached
                    # on body +z) pulls it anyway (holding the local vertical fought its torque)
                    coast = self._chute_coast(t, state)
                return ControlOutput(coast.throttles, coast.saturated, coast.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
            if self.phase in (Phase.ENTRY, Phase.PARACHUTE) and inner.mode != "coast":
                self._to(t, Phase.POWERED, f"braking curve reached at {self._altitude(state):.0f} m")
                self._fit_air(state)
                # the braking limb and the collective's throttle on the thrust the burn measured
                self.descent.T_v *= self.thrust_calibration.scale
            elif self.chute_first and self._chute_open and self.phase is Phase.PARACHUTE:
                # Still coasting under the chute: thrust axis along the airflow (as above), not the
                # descent law's upright hold, which fought the canopy's torque while the horizontal
                # speed decayed (4.7 kg from scenario 0's orbit). Its mode stays its own.
                coast = self._chute_coast(t, state)
                return ControlOutput(coast.throttles, coast.saturated, coast.unclipped, mode=self.phase.value,
                                     requests=inner.requests)
            if self.phase is Phase.POWERED and demand.altitude > 0 and self._settled(state, demand):
                self.hover.heading_W = self.landing.heading_W = self.descent.heading_W  # no yaw turn at the handover
                L = local_frame(state.r_W)
                self.hover.take_over(self.descent.horizontal_drag(L, self._altitude(state), np.zeros(3)))
                self._to(t, Phase.HOVER, f"fall stopped within {self.hover_speed:g} m/s at {self._altitude(state) - demand.altitude:+.1f} m from the hover")
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

    def _open_chute(self, t: float) -> None:
        """The descent law asked for the chute: its drag from now on, and entry ends."""
        self._chute_open = True
        self.descent.drag_k = self._drag_k
        if self.phase is Phase.ENTRY:
            self._to(t, Phase.PARACHUTE, "chute within its limits")

    def _before_chute(self, t: float, state: StateView) -> ControlOutput:
        """Entry, chute first, chute still packed: the entry command (:meth:`_entry_command`) and the
        descent law's chute request alone. Its throttles would not be flown here, so its whole update
        (ground-speed mixing, failure watch: ~0.4 ms, 18,000 times from scenario 0's orbit) is not run
        until the chute is out; it then starts from the chute's instant."""
        self._learn_density(t, state)
        request = self.descent._chute_request(self._altitude(state), self._climb_rate(state),
                                              float(np.linalg.norm(state.v_W)))
        if request is None:
            u = saturate(self._entry_command(t, state))
            self._coast_thrust = self.descent.T_v * float(np.mean(u.throttles))
            return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=self.phase.value)
        self._open_chute(t)
        u = saturate(self._retrograde(state, 0.0))
        return ControlOutput(u.throttles, u.saturated, u.unclipped, mode=self.phase.value, requests=(request,))

    def _waits_for_chute(self, state: StateView, demand: Demand) -> bool:
        """True while the chute-first descent coasts (no thrust; see :meth:`update`).

        Before the chute opens: while the lander is above the lowest altitude the descent law may
        open it at (``chute_min_altitude`` above contact and the floor); below that the law flies as
        it would without a chute. After it opens: while the chute's and body's drag alone decelerate
        the lander by more than the law's braking limb ``a_b`` (drag - weight > m a_b), which the law
        never asks more of: thrust then would only replace deceleration the drag gives for free.
        """
        if not self.chute_first:
            return False
        h = self._altitude(state)
        d = self.descent
        if not self._chute_open:
            return h - d.half_size - self.descent.floor > d.chute_min_altitude
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        mass = self.vehicle.mass(state.fuel)
        speed2 = float(state.v_W @ state.v_W)
        drag = self._drag_k * self.descent.drag_scale * MARS_ATMOSPHERE.density(h) * speed2
        return drag / mass - g > d.braking_acceleration(mass, g)

    def _learn_thrust(self, t: float, state: StateView, thrust: float) -> None:
        """De-orbit burn: one period's measured thrust acceleration against the model's
        (:class:`.calibration.ThrustCalibration`); ``thrust`` [N] is the axial thrust commanded for
        the period starting now. Both laws fly the powered descent on the scale: the MPC plans on it
        (``deorbit-mpc``), the scheduled law's ``T_v`` is scaled by it at the handover."""
        rn = float(np.linalg.norm(state.r_W))
        g_W = -c.GM_MARS * np.asarray(state.r_W, float) / rn**3
        prev = self._last_burn
        if prev is not None and t > prev[0] and prev[4] > 0.0:
            dt = t - prev[0]
            mass = 0.5 * (self.vehicle.mass(prev[3]) + self.vehicle.mass(state.fuel))
            self.thrust_calibration.add((state.v_W - prev[1]) / dt, 0.5 * (g_W + prev[2]), prev[4], mass)
        self._last_burn = (t, np.array(state.v_W, float), g_W, float(state.fuel), thrust)

    def _learn_density(self, t: float, state: StateView) -> None:
        """Entry, chute packed, coasting: the air's density against the model's, for the chute.

        Over a period ``v' = g_W + a_D + a_T``, ``|a_D| = k_body rho |v|^2 / m``, the thrust axis held
        retrograde, so ``|a_D| ~ |dv/dt - g_W| - T / m`` with ``T`` the axial thrust the attitude hold
        commanded (a few % of the maximum; periods with more, a braking entry, are skipped). The
        measured over the model's gives ``rho_true / rho_model`` (filtered, 2 s; only where the
        model's drag exceeds 0.5 m/s^2, so that the difference of velocities is not noise). The chute's
        predicted drag uses it (:attr:`LandingController.density_scale`): with +30 % of air the canopy,
        opened at 0.9 of its modelled drag limit, was torn off (a dispersed 200 km flight)."""
        prev, self._last_coast = self._last_coast, (t, np.array(state.v_W, float))
        thrust, self._coast_thrust = self._coast_thrust, math.inf
        if prev is None or t <= prev[0] or thrust > 0.05 * self.descent.T_v:
            return
        h = self._altitude(state)
        rn = float(np.linalg.norm(state.r_W))
        speed2 = float(state.v_W @ state.v_W)
        mass = self.vehicle.mass(state.fuel)
        model = 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA * MARS_ATMOSPHERE.density(h) * speed2 / mass
        if model < 0.5:
            return
        measured = float(np.linalg.norm((state.v_W - prev[1]) / (t - prev[0]) + c.GM_MARS * state.r_W / rn**3)) - thrust / mass
        ratio = min(max(measured / model, 0.3), 3.0)
        d = self.descent
        d.density_scale += min((t - prev[0]) / 2.0, 1.0) * (ratio - d.density_scale)

    def _chute_coast(self, t: float, state: StateView) -> ControlOutput:
        """Under the open chute, no collective: the thrust axis held against the velocity, and the
        drag measured (:meth:`_learn_drag`)."""
        self._learn_drag(t, state)
        coast = saturate(self._retrograde(state, 0.0))
        # the thrust this period flies [N, world], for the next period's measured drag
        self._coast_thrust_W = (self.descent.T_v * self.thrust_calibration.scale * float(np.mean(coast.throttles))
                               * quat_to_matrix(state.q)[2])
        return coast

    def _fit_air(self, state: StateView) -> None:
        """At the powered descent's start: the density scale and mean wind over the coast under the
        chute (:class:`.calibration.ChuteDragFit`), from the scale learnt and the drift as first guess."""
        up = state.r_W / float(np.linalg.norm(state.r_W))
        drift = state.v_W - float(state.v_W @ up) * up
        self.air = self.air_fit.solve(self.descent.drag_scale, drift)
        self.descent.air = self.air
        self.descent.drift_W = drift
        w = self.descent.wind_W
        self.descent.wind_h = float(np.linalg.norm(w - float(w @ up) * up))
        self.descent.wind_up = float(w @ up)  # read only with a fit (without one, w is the horizontal drift)

    def _learn_drag(self, t: float, state: StateView) -> None:
        """Under the open chute with the thrusters off: the drag the air really gives against the model's.

        Vertically ``h'' = -g + c_true h'^2`` with no thrust, so each period's measured acceleration
        (difference of climb rates) gives ``c_true / c_model = (h'' + g) / (c_model h'^2)``; filtered
        with a 2 s time constant. It folds a density, a drag coefficient or a mass off the model into one
        number, which the braking limb then uses (:attr:`DescentToAltitude.drag_scale`). Without it a
        30 % thinner atmosphere than modelled leaves the limb ~1 m/s^2 short of its deceleration near
        the chute's terminal speed, five times the law's thrust margin: the lander braked 28 m past
        the hover altitude in a dispersed sweep flight.

        Each period also gives the fit of the drag's scale and the wind over the whole coast
        (:class:`.calibration.ChuteDragFit`, solved at the powered descent's start, :meth:`_fit_air`):
        the measured drag vector, the thrust commanded over the period taken off. The MPC plans on
        that fit, and so does the scheduled law from then on: its braking limb (:class:`FallDrag`)
        and its horizontal loop's drag fed forward (:meth:`DescentToAltitude.horizontal_acceleration`).
        The scalar above sets the limb's curve until the fit, the braking's first instant included."""
        h = self._altitude(state)
        climb = self._climb_rate(state)
        prev, self._last_climb = self._last_climb, (t, climb)
        before, self._last_air = self._last_air, (t, np.array(state.v_W, float), np.array(state.r_W, float), float(state.fuel))
        if before is not None and t > before[0]:
            dt = t - before[0]
            r_mid = 0.5 * (state.r_W + before[2])
            rn = float(np.linalg.norm(r_mid))
            mass = self.vehicle.mass(0.5 * (state.fuel + before[3]))
            drag_W = (state.v_W - before[1]) / dt + c.GM_MARS * r_mid / rn**3 - self._coast_thrust_W / mass
            k = self._drag_k * MARS_ATMOSPHERE.density(rn - c.MARS_RADIUS) / mass
            self.air_fit.add(0.5 * (state.v_W + before[1]), drag_W, k)
        if prev is None or t <= prev[0] or climb > -5.0:
            return
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        c_model = self._drag_k * MARS_ATMOSPHERE.density(h) / self.vehicle.mass(state.fuel)
        ratio = ((climb - prev[1]) / (t - prev[0]) + g) / (c_model * climb * climb)
        ratio = min(max(ratio, 0.3), 3.0)
        self.descent.drag_scale += min((t - prev[0]) / 2.0, 1.0) * (ratio - self.descent.drag_scale)

    def _entry_command(self, t: float, state: StateView) -> np.ndarray:
        """Before the chute: thrust axis retrograde; brake (``burn_throttle``) only while a drag-only
        prediction of the rest of the entry (:func:`.guidance.deorbit.fly_entry`, re-run every
        ``predict_every`` s) says the chute could not open within the margin's limits at or above
        ``chute_altitude``. The chute is the cheapest brake: thrust only buys the speed it needs."""
        if t - self._predicted_at >= self.predict_every:
            self._predicted_at = t
            check = fly_entry(state.r_W, state.v_W, self.vehicle.mass(state.fuel), self.chute_vehicle)
            self._entry_brake = not (check.survivable and check.chute_altitude >= self.chute_altitude)
        retro = -state.v_W / float(np.linalg.norm(state.v_W))
        d = self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state)
        return mix_with_attitude_priority(self.burn_throttle if self._entry_brake else 0.0, d)

    def _retrograde(self, state: StateView, collective: float) -> np.ndarray:
        """Throttles holding the thrust axis against the velocity (attitude priority) [unclipped]."""
        retro = -state.v_W / max(float(np.linalg.norm(state.v_W)), 1e-9)
        return mix_with_attitude_priority(collective, self.attitude.command_toward(thrust_axis_attitude(state.q, retro), state))

    @staticmethod
    def _altitude(state: StateView) -> float:
        return float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS

    @staticmethod
    def _climb_rate(state: StateView) -> float:
        """Velocity along the local vertical [m/s], up positive."""
        # R + h rather than |r|: the arithmetic the law's callers used inline, bit for bit
        return float(state.v_W @ state.r_W) / (c.MARS_RADIUS + DeorbitController._altitude(state))

    def _settled(self, state: StateView, demand: Demand) -> bool:
        """The fall is stopped (climb rate within ``hover_speed`` of zero, or climbing) at or under
        the top of the hover band: the hover law takes the rest out (a drift in the wind, or an
        altitude below the band after braking short on a thinner atmosphere than modelled)."""
        h = self._altitude(state)
        climb = self._climb_rate(state)
        return h - demand.altitude <= self.hover_band and (
            abs(climb) <= self.hover_speed if h - demand.altitude >= -self.hover_band else climb >= -self.hover_speed)

    def start_in(self, phase: Phase, chute_open: bool = False) -> None:
        """Begin the mission at ``phase`` (ENTRY or later) with no de-orbit plan: for flights that
        start from a state inside the atmosphere, e.g. one handover case flown by both descent laws."""
        if phase in (Phase.SLEW, Phase.BURN, Phase.COAST):
            raise ControllerError(f"start_in: the phases before entry need the de-orbit plan, got {phase.value!r}")
        self.reset()
        self.phase, self._chute_open = phase, bool(chute_open)
        self.descent.drag_k = self._drag_k if chute_open else 0.0
        self.descent._chute_requested = self._chute_open  # the chute is out: the law must not ask again

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        if self.phase not in (Phase.SLEW, Phase.BURN, Phase.COAST):
            return np.zeros(self.n_thrusters)  # from entry on, update() flies the descent laws
        if self.plan is None:
            self._t0 = t
            self.plan = plan(state.r_W, state.v_W, self.vehicle.mass(state.fuel), self.entry_vehicle,
                             slew_time=self.slew_time, min_chute_altitude=self.chute_altitude)
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

