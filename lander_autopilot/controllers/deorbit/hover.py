"""Hover capture: the hover after the powered descent, the ground-speed law with its altitude loop
a capture that does not set a lander at rest in the band moving. Core code (no rclpy), SI units.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..base import ControlOutput, Demand
from ..ground_speed import GroundSpeedController

#: The hover's attitude poles [1/s]: twice the ground-speed law's -2 (eight times its velocity loop's
#: -0.5). Under the canopy in a wind the hover takes over with the thrust axis short of the tilt the
#: drag at rest needs; at -2 it flies there slowly, on hover thrust, and at -4 on about half the fuel
#: (``test_hover_attitude_fast_enough_to_take_the_last_drift_out_under_the_canopy``). -4 is 0.4 rad
#: per 0.1 s period.
HOVER_ATTITUDE_POLES: tuple[float, ...] = (-4.0,) * 6
#: [m] the hover band: the powered descent hands over to the hover within this of the demand
#: altitude, the hover holds it within it (the mission's ``hover_band``); the de-orbit sweeps' own
#: success band, the task's "hover at a fixed altitude" held to the lander's size
HOVER_BAND = 2.0
#: [m/s] ... at a climb rate within this (the mission's ``hover_speed``): the sweeps' "at rest"
HOVER_SPEED = 0.2


class HoverCapture:
    """The hover after the powered descent: the ground-speed law, its altitude loop a capture.

    A part: it holds the ground-speed law it flies (:attr:`law`) as that law's vertical loop
    (:attr:`..ground_speed.GroundSpeedController.vertical_law`); ``update`` is the law's.

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
    zero, the wind sets the lander drifting faster as the hover begins (0.17 -> 0.24 m/s over 1.5 s
    in a dispersed 200 km flight), seconds of hover thrust to the band at rest. The braking's integral
    action on the thrust axis (:meth:`.descent.DescentToAltitude.axis_bias`) is not carried on here: over
    the 30 s hold it set the horizontal loop oscillating, growing, and 13 of the 200 km sweep's
    200 flights fell from the hover. Its attitude law is
    faster than the ground-speed law's (:data:`HOVER_ATTITUDE_POLES`, set by the mission): the tilt
    the wind needs at rest is flown before the drift the braking left can grow.
    """

    band: float = HOVER_BAND
    speed: float = HOVER_SPEED
    APPROACH: ClassVar[float] = 0.5  # of ``speed``: the climb rate allowed inside the band
    POSITION_GAIN: ClassVar[float] = 0.5  # [1/s] climb-rate demand per metre of error
    CAPTURE_ACCEL: ClassVar[float] = 1.0  # [m/s^2] braking into the band from outside it
    RATE_GAIN: ClassVar[float] = 2.0  # [1/s] thrust acceleration per m/s of climb-rate error
    AT_REST: ClassVar[float] = 0.8  # of ``speed``: the total speed the approach inside the band keeps under

    def __init__(self, vehicle: Vehicle, **params: Any) -> None:
        """``params``: the ground-speed law's (the mission sets ``attitude_poles``)."""
        self.law = GroundSpeedController(vehicle, **params)
        self.law.vertical_law = self

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        """The ground-speed law's step, its vertical loop this capture's."""
        return self.law.update(t, state, demand)

    def reset(self) -> None:
        """Forget the flight (the law's integrators and memories)."""
        self.law.reset()

    def take_over(self, drag: np.ndarray) -> None:
        """Start from the braking's end with the horizontal loop's integral preset to hold against
        ``drag`` (the drag's horizontal acceleration at rest, ENU [m/s^2]): the tilt the wind needs
        is asked for at once."""
        self.law.preset_velocity_integral(np.asarray(drag, float) / self.law.k_i)

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        """Thrust acceleration along up [m/s^2]: the capture (class docstring)."""
        e = h - demand.altitude
        # inside the band the climb rate allowed leaves room for the ground speed under ``speed``
        v_local = self.law.v_local
        v_h = math.hypot(float(v_local[0]), float(v_local[1]))
        v_in = min(self.APPROACH * self.speed, math.sqrt(max((self.AT_REST * self.speed) ** 2 - v_h * v_h, 0.0)))
        outside = abs(e) - self.band
        cap = v_in if outside <= 0.0 else math.sqrt(v_in * v_in + 2.0 * self.CAPTURE_ACCEL * outside)
        v_d = -math.copysign(min(self.POSITION_GAIN * abs(e), cap), e)
        r = c.MARS_RADIUS + h
        return c.GM_MARS / (r * r) + self.RATE_GAIN * (v_d - hd)

