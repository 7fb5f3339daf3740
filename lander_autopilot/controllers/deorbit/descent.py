"""The scheduled powered descent: the landing law's vertical loop redesigned to end at rest over
the demand altitude, with the drag of the open chute and of the fitted air on a braking limb.

:class:`DescentToAltitude` flies from the atmosphere's top to the hover: it asks for the chute
(the landing law's request), coasts above its braking curve and brakes on it. Its braking limb in
still air has a closed form (:func:`still_air_limb_speed`); in the air fitted under the chute
(scale and wind, :class:`.calibration.AirFit`) it is :class:`FallDrag`'s ODE, integrated and
inverted each period. Core code (no rclpy), SI units.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ...design.schedule import GainSchedule
from ..base import ControlOutput, Demand
from ..calibration import AirFit
from ..combined import CollectiveHeadroom, Mix
from ..landing import COAST_THRESHOLD_G, MODES, LandingController
from .geometry import AXIS_LIMIT, AXIS_UP_FLOOR, AxisIntegral


def still_air_limb_speed(a_b: float, cd: float, h_c: float) -> float:
    """Fall speed [m/s] from which the braking limb stops in ``h_c`` [m] under thrust deceleration
    ``a_b`` [m/s^2] and a drag ``cd v^2`` in still air (``cd`` [1/m]): ``v^2 = (a_b / cd)(e^{2 cd h_c} - 1)``,
    ``2 a_b h_c`` without drag."""
    return math.sqrt((a_b / cd) * math.expm1(2.0 * cd * h_c)) if cd > 0.0 else math.sqrt(2.0 * a_b * h_c)


#: [m] the braking limb ends this far above the floor, inside the hover band (2 m): a braking that
#: falls short still stops in the band instead of climbing back to it. The limb's margin is kept
#: here, in height, more than in thrust (``brake_fraction`` 0.96): a braking that falls behind its
#: limb ends lower, which costs nothing while it stays in the band; thrust held back costs every
#: flight a longer burn. 1.75 m keeps the 200 km sweep's hardest braking (a thruster 3 % weak in a
#: 5.6 m/s drift, ``test_limb_margin_in_height_keeps_a_braking_that_falls_behind_in_the_band``)
#: inside the band (the mission's ``stop_above``).
STOP_ABOVE = 1.75
#: [s] the attitude's lag to a new tilt under the canopy, braking (the mission's ``braking_lag``), and
#: [s] of the braking left at which the ground speed is to be out (``braking_settle``): with the fall
#: past the limb's end braked at ``a_b`` the braking is short, and a longer lag term holds the
#: horizontal loop's time constant near ``tau + lag`` at the end, so the windiest flights begin the
#: hover drifting; every pair in 0.45-0.55 s and 0.6-1.2 s gives the same count of flights within
#: 1.05 x the optimum over both de-orbit sweeps (:meth:`DescentToAltitude.horizontal_acceleration`)
BRAKING_LAG = 0.5
BRAKING_SETTLE = 0.8

#: Newton steps, at most, inverting the limb's stopping height from the still-air form: a bound
#: on the work of a control period (the loop ends as soon as LIMB_TOLERANCE is met)
LIMB_NEWTON_STEPS = 8
#: [-] relative height error (of ``max(h_c, 1 m)``) at which the limb's speed is taken as found:
#: a micrometre in a metre, far under what a control period moves
LIMB_TOLERANCE = 1e-6
#: [m/s] floor of a Newton step's speed: the limb's speed stays positive (a divisor)
LIMB_MIN_SPEED = 1e-6

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
        for _ in range(LIMB_NEWTON_STEPS):
            f = self.stopping_height(a_b, v) - h_c
            v = max(v - f * (a_b + self.deceleration(v)) / v, LIMB_MIN_SPEED)
            if abs(f) < LIMB_TOLERANCE * max(h_c, 1.0):
                break
        return v


class DescentToAltitude:
    """The landing law's vertical loop redesigned to end at rest on ``floor`` [m] (the demand altitude).

    A part: it holds the landing law it flies (:attr:`law`, a :class:`..landing.LandingController`
    built with this part as its :class:`..landing.DescentProfile`), which asks it for the vertical
    loop, the braking deceleration, the horizontal loop while braking, the thrust axis's correction,
    the heading and the tilt limit, and tells it each mix. ``update``, ``reset`` and the chute's
    request are the law's; the part reads and sets the law through its public members only.

    Braking limb: constant thrust deceleration ``a_b`` (``brake_fraction`` of the net thrust
    acceleration at the current mass, on the collective the attitude law leaves: ``headroom``,
    :class:`.combined.CollectiveHeadroom`, learnt while braking; ``T_v`` the thrust the de-orbit
    burn measured, :class:`.calibration.ThrustCalibration`) plus the quadratic drag ``c v^2``,
    ``c = drag_k rho(h) / m`` (``drag_k``: ``sum 1/2 Cd A`` of canopy and body [m^2] once the chute
    is out, else 0; density held at the current altitude's over the limb: it only grows below, so
    the curve is conservative). ``d(v^2)/dh = 2 (a_b + c v^2)`` through ``(floor + stop_above, 0)``
    gives the descent-rate demand ``v_d^2 = (a_b / c)(e^{2 c h_c} - 1)``, ``h_c = h - floor -
    stop_above`` (``2 a_b h_c`` without drag). There is no flare: the limb itself ends at rest in
    the hover band, as the minimum-fuel descent does (full thrust to the last instant); a flare's
    slow end costs hover thrust, ~7 % of the powered fuel a second here. The deceleration asked for
    is capped at what stops the fall within one control period, so the last period does not
    reverse the speed.

    Once the air is fitted under the chute (:class:`.calibration.AirFit`, at the powered descent's
    start) the drag is the fitted air's on a fall through the fitted wind (:class:`FallDrag`: the
    wind's vertical part moves the airspeed, so the drag no longer scales as ``v^2``), and the limb
    is that ODE's, ``dh/dv = v / (a_b + D(v))``, integrated and inverted each period. On the learnt
    scale alone the fuel grows with the vertical wind: a scale learnt at the canopy's terminal speed
    reads an updraft as denser air (:class:`.estimation.OnlineEstimator`).

    Thrust acceleration along up: ``a_U = g + dv_d/dt + c h' |h'| + k(m, d) (T_v / m) (v_d - h')``,
    ``dv_d/dt = (a_b + c v_d^2) h' / v_d`` (chain rule, capped at the limb's own deceleration as
    ``v_d -> 0``): the limb's deceleration fed forward, the drag the air gives taken off (upward
    while falling), and the velocity loop, whose gain ``k`` [throttle per m/s] is **scheduled**
    over the mass and the drag's damping ``d = 2 c |h'|`` (:func:`...design.schedule.schedule_descent_rate`:
    the pole stays at ``descent_pole`` as the air and the tank change the plant). Past the limb's
    end (``h_c <= 0``) it climbs back at ``RETURN_RATE`` per metre, and while still falling there it
    brakes at no less than the limb's ``a_b`` (the one-period cap then ends the fall on the control
    grid): a braking that falls behind its limb (the collective saturated) passes the end still
    falling, and a loop whose demand shrinks with its error there creeps the last metres per second
    out at part of the collective, on hover-like thrust (test_deorbit_windy.py,
    ``test_fall_past_the_limbs_end_is_stopped_at_the_limbs_deceleration``).

    Horizontally, while braking, the ground speed is taken out over the braking left
    (:meth:`horizontal_acceleration`) and the thrust axis the attitude law flies short of its
    demand under the canopy is corrected by integral action (:meth:`axis_bias`).
    """

    floor: float = 0.0
    drag_k: float = 0.0
    drag_scale: float = 1.0  # measured drag / modelled drag under the chute (.estimation.ChuteDragLearner)
    rate_schedule: GainSchedule | None = None
    RETURN_RATE: ClassVar[float] = 1.0  # [1/s] climb-back demand per metre below the floor
    #: [m] the limb ends this far above the floor (:data:`STOP_ABOVE`; the mission's ``stop_above``)
    stop_above: float = STOP_ABOVE
    #: [s] of the braking left at which the ground speed is to be out (the mission's ``braking_settle``)
    settle: float = BRAKING_SETTLE
    TAU_MIN: ClassVar[float] = 0.7  # [s] shortest time constant of the horizontal loop (horizontal_acceleration)
    #: [s] the attitude's lag to a new tilt under the canopy, braking (the mission's ``braking_lag``)
    lag: float = BRAKING_LAG
    axis_time: float = 1.0  # [s] integral time of the thrust axis's correction (axis_bias)
    #: largest correction of the thrust axis, horizontal / vertical part (~11 deg; 0: none; the
    #: mission's ``axis_limit``)
    axis_limit: float = AXIS_LIMIT
    #: the horizontal loop's lag term counts, where the mixer's ceiling bound, the thrust it gave
    #: (True) rather than the thrust asked (the mission's ``lag_counts_ceiling``)
    lag_counts_ceiling: bool = True
    #: learn the attitude law's share of the collective while braking (the mission's ``learn_headroom``)
    learn_headroom: bool = True
    #: [m/s] horizontal wind (fitted under the chute) from which the headroom also learns at the
    #: mixer's floor (:meth:`mixed`); below it only where the ceiling binds
    FLOOR_LEARN_WIND: ClassVar[float] = 4.0
    #: No thruster-failure watch (nor probe burns) on the way down from orbit. The watch's chute
    #: model learns the wind while coasting slowly under the canopy; opened at entry speeds in a
    #: wind, the canopy's unexplained torque (~10 N m per m/s of wind at 40 m/s, growing with the
    #: airspeed squared) looks like a dead thruster within 0.2 s. In the 200 km sweep (200 flights,
    #: no failure drawn) that false alarm switched 7 of the 8 worst flights to the three-thruster
    #: spinning descent: 1.6-2.1 x the optimum's fuel, braking 70-140 m under the hover.
    detects_failures: bool = False

    def __init__(self, vehicle: Vehicle, **params: object) -> None:
        """``params``: the landing law's (:attr:`..landing.LandingController.PARAMS`)."""
        self.law = LandingController(vehicle, profile=self, **params)
        self.reset()

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        """The landing law's step, flown on this part's profile."""
        return self.law.update(t, state, demand)

    def reset(self) -> None:
        """Forget the flight: the law's state, and this part's (the headroom, the air, the winds)."""
        self.law.reset()
        self._time_to_go = 0.0  # [s] braking left on the limb (vertical_acceleration sets it)
        self.headroom = CollectiveHeadroom()  # what the attitude law takes of the collective, braking
        self.air: AirFit | None = None  # the air fitted under the chute (.estimation.ChuteDragLearner.fit)
        self.drift_W = np.zeros(3)  # [m/s, world] horizontal velocity at the braking's start: the wind without a fit
        self.wind_h = 0.0  # [m/s] the horizontal wind at the braking's start (fitted, else the drift)
        self.wind_up = 0.0  # [m/s] the fitted wind's vertical part (up positive)
        self._a_up = 0.0  # [m/s^2] this period's thrust acceleration along up (vertical_acceleration)
        #: [m/s^2] the axial thrust acceleration the mixer gave last period if its ceiling bound
        #: (``T_v mean(u) / m``), else None (:meth:`mixed`, :meth:`horizontal_acceleration`)
        self._axial_at_ceiling: float | None = None
        self.axis_integral = AxisIntegral(self.axis_time, self.axis_limit)  # axis_bias's, braking

    @property
    def wind_W(self) -> np.ndarray:
        """The wind the braking plans on [m/s, world]: the fit under the chute, else the drift."""
        return self.drift_W if self.air is None else self.air.wind_W

    def braking_acceleration(self, mass: float, g: float) -> float:
        """The limb's ``a_b`` on the collective the attitude law leaves (:class:`.combined.CollectiveHeadroom`)."""
        law = self.law
        return law.brake_fraction * max(self.headroom.available * law.T_v / mass - g, 0.0)

    def mixed(self, m: Mix) -> None:
        """Braking: the attitude law's share of the collective learnt from the mix ``m`` (:class:`.combined.CollectiveHeadroom`),
        and the axial thrust the mixer's ceiling gave kept for the next period's horizontal loop."""
        law = self.law
        if law.mode != "coast" and self.learn_headroom:
            u = m.throttles if m.mixed_from is None else m.mixed_from
            top = float(u.max())
            # Learn where the ceiling binds; in a strong wind also where the mixer gave way at the
            # floor (as the braking begins, the thrust axis turning against the canopy): there the
            # attitude law's differential through the braking is large, and learnt only once the
            # ceiling binds it comes too late (200 km sweep, winds over 4.3 m/s: 1.15-1.40 x the
            # optimum). In lighter winds the floor's one period teaches a share of ~0.03 that the
            # braking never needs, ~1 % of fuel on the typical flight.
            at_floor = self.wind_h >= self.FLOOR_LEARN_WIND and m.mixed_from is not None
            self.headroom.update(top - law.collective.level, at_floor or top >= 1.0, law.control_period)
        self._axial_at_ceiling = self.axial_at_ceiling(m)

    def axial_at_ceiling(self, m: Mix) -> float | None:
        """Braking: the axial thrust acceleration [m/s^2] the mix ``m`` gives where its ceiling binds,
        ``T_v mean(u) / m`` (``u`` clipped to [0, 1]); None where it does not, and in the coast."""
        if not self.lag_counts_ceiling or self.law.mode == "coast" or float(m.throttles.max()) < 1.0:
            return None
        return self.law.T_v * float(np.clip(m.throttles, 0.0, 1.0).mean()) / self.law.mass

    def rate_gain(self, damping: float) -> float:
        """Velocity-loop acceleration gain [1/s] at the current mass and drag damping ``d`` [1/s]."""
        if self.rate_schedule is None:
            return self.law.k_v
        mass = self.law.mass
        k = float(self.rate_schedule.gain((mass, damping))[0, 0])
        return k * self.law.T_v / mass

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        """Thrust acceleration along up [m/s^2] on the braking limb to the floor (class docstring);
        the law's mode leaves the coast once it asks for a tenth of gravity."""
        law = self.law
        mass = law.mass
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        a_b = self.braking_acceleration(mass, g)
        h_c = h - self.floor - self.stop_above
        air = self.air
        if air is None or self.drag_k <= 0.0:
            # no fit (chute packed, or a flight begun under it): the scale learnt, still air
            cd = self.drag_k * self.drag_scale * MARS_ATMOSPHERE.density(h) / mass
            if h_c > 0.0:
                v = still_air_limb_speed(a_b, cd, h_c)
                limb = a_b + cd * v * v  # the limb's deceleration at v
            drag_up, damping = -cd * hd * abs(hd), 2.0 * cd * abs(hd)
        else:
            wind = FallDrag(self.drag_k * air.scale * MARS_ATMOSPHERE.density(h) / mass, self.wind_up, self.wind_h)
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
            a_up = min(a_up, g - drag_up - hd / law.control_period)
        if a_up >= COAST_THRESHOLD_G * g and law.mode == "coast":
            law.mode = MODES[1]
        self._a_up = a_up
        return a_up

    def horizontal_acceleration(self, state: StateView, L: np.ndarray, h: float, v_L: np.ndarray,
                                error: np.ndarray) -> np.ndarray | None:
        """Braking: the ground speed nulled over the braking left, with the drag fed forward and the
        attitude's lag allowed for (before it, and to a floor of 0, the ground-speed law's PI).

        ``a_h = -(e + lag a_flown) / tau - a_D``, ENU [m/s^2]: ``e`` the horizontal velocity error,
        ``tau = max(t_go - settle, TAU_MIN)`` (``t_go``: the braking left on the limb at its present
        deceleration, an underestimate, so the speed is out ``settle`` s before it), ``a_D`` the
        drag's horizontal part, ``-s K rho |v - w| (v - w)`` with the air fitted over the coast under
        the chute (:class:`.calibration.AirFit`: scale ``s`` and the wind ``w``, vertical part
        included; without a fit the drag scale learnt and the drift as the wind), and ``a_flown`` the
        horizontal acceleration the thrust axis flies now (thrust along the current body z) plus
        ``a_D``: the attitude reaches a new tilt ~``lag`` s after it is asked for, and the speed
        that lag still takes out is not asked for twice. The thrust in ``a_flown`` is the one asked
        for (``a_U`` along up), or, where the mixer's ceiling bound last period, no more than the
        one it gave (``T_v mean(u) / m`` along the axis; ``lag_counts_ceiling``): in a strong wind
        the braking rides the ceiling (the attitude law's share on top of the collective), the
        thrust flown falls 10-30 % under the one asked for, and counting the thrust asked takes
        that missing thrust's horizontal part as speed already being taken out, so the hover begins
        drifting (``test_braking_at_the_mixers_ceiling_counts_the_thrust_it_gives_not_the_one_asked``).

        ``lag`` and ``settle``: :data:`BRAKING_LAG`, :data:`BRAKING_SETTLE`
        (``test_braking_takes_the_drift_out_before_its_shorter_end``). The loop's integral is held at 0 (it winds up on the drift while
        coasting).
        """
        if self.floor <= 0.0 or self.law.mode == "coast":
            return None
        self.law.clear_velocity_integral()
        drag = self.horizontal_drag(L, h, v_L)
        z_L = L @ quat_to_matrix(state.q)[2]  # the thrust axis flown, ENU
        axial = self._a_up / max(float(z_L[2]), AXIS_UP_FLOOR)
        if self._axial_at_ceiling is not None:
            axial = min(axial, self._axial_at_ceiling)
        flown = axial * z_L[:2] + drag
        tau = max(self._time_to_go - self.settle, self.TAU_MIN)
        return -(error + self.lag * flown) / tau - drag

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
        cd = self.drag_k * scale * MARS_ATMOSPHERE.density(h) / self.law.mass
        return -cd * float(np.linalg.norm(rel)) * rel[:2]

    def axis_bias(self, t: float, state: StateView, L: np.ndarray, wanted: np.ndarray) -> np.ndarray | None:
        """Braking: integral action on the thrust axis the attitude law flies against the one wanted
        (:class:`.geometry.AxisIntegral`, ``axis_time`` and ``axis_limit``); none outside the braking.

        Under the canopy the attitude law (proportional-derivative) flies the thrust axis short of
        its demand: the canopy's torque pulls body +z back toward the airflow, and the axis flies
        under half the tilt asked for through the braking, leaving the hover the drift to take out
        on hover thrust (``test_thrust_axis_correction_takes_the_drift_out_by_the_hover``).
        """
        if self.floor <= 0.0 or self.law.mode == "coast":
            self.axis_integral.pause()
            return None
        if self.axis_limit == 0.0:
            return None
        return self.axis_integral.update(t, state.q, L, wanted)

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray | None:
        """None (the law's heading), after setting the law's ``heading_W`` (below)."""
        # From the braking on, the heading is the one the body had as it began (``heading_W``, world
        # frame; the hover and the landing keep it). The canopy leaves the body x anywhere; turning it
        # back to east as the braking started (0.9 rad/s of yaw from the canted thrusters'
        # differential throttle) took half of two thrusters for ~2 s of the braking, and the fall ran
        # under the hover. A heading free at every instant (the current body x) cost 1.5 % of the
        # nominal fuel: the yaw rate was never brought to rest.
        law = self.law
        if law.mode == "coast":
            law.heading_W = None
        elif law.heading_W is None:
            law.heading_W = quat_to_matrix(state.q)[0].copy()
        return None

    def tilt_limit(self, h: float) -> float | None:
        # the floor is a hover, not a touchdown: the full tilt stays, so the ground speed the chute
        # drifted with in the wind is taken out (the landing law shrinks it to stand upright)
        return self.law.max_tilt if self.floor > 0.0 else None

