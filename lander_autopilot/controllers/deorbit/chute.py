"""The chute decision of the de-orbit mission: whether the descent coasts for the chute, and whether
the entry, chute still packed, must brake so that the chute can open within its limits.

Chute first: the canopy takes the lander from ~250 m/s to its terminal ~37 m/s for no fuel, so
the mission coasts (no thrust) while the chute is still to open, or still brakes harder than the
descent law's braking limb would, and brakes before it only where a drag-only prediction of the
rest of the entry says the chute could not open within its margin. Core code, SI units.
"""
from __future__ import annotations

import math

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ...guidance.deorbit import EntryVehicle, fly_entry
from .descent import DescentToAltitude
from .geometry import altitude


class ChuteDecision:
    """``chute_vehicle`` the entry predictor's vehicle (the canopy's limits with the mission's
    margin), ``chute_altitude`` [m] the lowest predicted opening, ``predict_every`` [s] the
    prediction's period, ``drag_k`` [m^2] ``sum 1/2 Cd A`` of canopy and body."""

    def __init__(self, vehicle: Vehicle, chute_vehicle: EntryVehicle, chute_altitude: float,
                 predict_every: float, drag_k: float) -> None:
        self.vehicle = vehicle
        self.chute_vehicle = chute_vehicle
        self.chute_altitude = chute_altitude
        self.predict_every = predict_every
        self.drag_k = drag_k
        self.reset()

    def reset(self) -> None:
        self._predicted_at = -math.inf
        self.entry_brake = False  # the last prediction: the entry must brake for the chute

    def waits(self, state: StateView, chute_open: bool, descent: DescentToAltitude) -> bool:
        """True while the chute-first descent coasts (no thrust).

        Before the chute opens: while the lander is above the lowest altitude the descent law may
        open it at (``chute_min_altitude`` above contact and the floor); below that the law flies as
        it would without a chute. After it opens: while the chute's and body's drag alone decelerate
        the lander by more than the law's braking limb ``a_b`` (drag - weight > m a_b), which the law
        never asks more of: thrust then would only replace deceleration the drag gives for free.
        """
        h = altitude(state)
        d = descent
        if not chute_open:
            return h - d.law.half_size - descent.floor > d.law.chute_min_altitude
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        mass = self.vehicle.mass(state.fuel)
        speed2 = float(state.v_W @ state.v_W)
        drag = self.drag_k * descent.drag_scale * MARS_ATMOSPHERE.density(h) * speed2
        return drag / mass - g > d.braking_acceleration(mass, g)

    def entry_brakes(self, t: float, state: StateView) -> bool:
        """Before the chute: whether to brake now. Re-run every ``predict_every`` s, a drag-only
        prediction of the rest of the entry (:func:`...guidance.deorbit.fly_entry`) says whether the
        chute could open within the margin's limits at or above ``chute_altitude``; the entry brakes
        only while it could not. The chute is the cheapest brake: thrust only buys the speed it needs."""
        if t - self._predicted_at >= self.predict_every:
            self._predicted_at = t
            check = fly_entry(state.r_W, state.v_W, self.vehicle.mass(state.fuel), self.chute_vehicle)
            self.entry_brake = not (check.survivable and check.chute_altitude >= self.chute_altitude)
        return self.entry_brake

