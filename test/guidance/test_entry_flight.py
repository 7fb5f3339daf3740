"""The compiled entry predictor against scipy's RK45 and against itself at half the step.

The de-orbit law asks the drag-only entry question once a second of flight; the compiled RK4 kernel
(:mod:`lander_autopilot.guidance.entry_flight`) answers it ~300 times faster than ``solve_ivp`` did.
Its error is fourth order in the step: halving ``step_scale`` must shrink the chute altitude's error
about 2^4 = 16 times, and the independent RK45 solution (rtol 1e-9) must lie within the error the
step-halving estimates (Richardson: |y_h - y_h/2| * 16 / 15), doubled for safety.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lander_autopilot.guidance.deorbit import EntryVehicle, fly_entry
from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE as ATM

VEHICLE = EntryVehicle(axial_thrust=4 * c.LANDER_MAX_THRUST * math.cos(math.atan(0.25)),
                       fuel_rate=4 * c.LANDER_FUEL_RATE)
GM, R = c.GM_MARS, c.MARS_RADIUS


def reference(r0: np.ndarray, v0: np.ndarray, mass: float) -> tuple[float, float]:
    """(chute altitude [m], chute speed [m/s]) by scipy RK45 with event location, rtol 1e-9 (the
    predictor's former implementation)."""
    kd = 0.5 * VEHICLE.drag_cd * VEHICLE.drag_area / mass
    kc = 0.5 * VEHICLE.chute_cd * VEHICLE.chute_area

    def f(_t, y):
        r = np.linalg.norm(y[:3])
        return np.concatenate([y[3:], -GM * y[:3] / r**3 - kd * ATM.density(r - R) * np.linalg.norm(y[3:]) * y[3:]])

    def chute_ok(_t, y):
        h, v = np.linalg.norm(y[:3]) - R, np.linalg.norm(y[3:])
        if h > ATM.exosphere:
            return 1.0
        return max(v - VEHICLE.chute_max_speed, kc * ATM.density(h) * v * v - VEHICLE.chute_max_drag)

    chute_ok.terminal, chute_ok.direction = True, -1
    sol = solve_ivp(f, (0, 20_000.0), np.concatenate([r0, v0]), rtol=1e-10, atol=1e-7, max_step=5.0,
                    events=chute_ok)
    y = sol.y_events[0][0]
    return float(np.linalg.norm(y[:3]) - R), float(np.linalg.norm(y[3:]))


def _after_burn(orbit_altitude: float, periapsis: float) -> tuple[np.ndarray, np.ndarray]:
    r0, rp = R + orbit_altitude, R + periapsis
    return np.array([r0, 0.0, 0.0]), np.array([0.0, -math.sqrt(2 * GM * rp / (r0 * (r0 + rp))), 0.0])


CASES = {
    "1.2 R to 60 km": (*_after_burn(0.2 * R, 60e3), 190.0),
    "200 km to 100 km": (*_after_burn(200e3, 100e3), 195.0),
    "inside, 80 km": (np.array([R + 80e3, 0.0, 0.0]), np.array([-300.0, -3300.0, 100.0]), 170.0),
}


@pytest.mark.parametrize("case", CASES)
def test_chute_instant_converges_at_fourth_order_onto_rk45(case):
    r0, v0, mass = CASES[case]
    full, half, quarter = (fly_entry(r0, v0, mass, VEHICLE, step_scale=s) for s in (1.0, 0.5, 0.25))
    assert full.survivable and half.survivable and quarter.survivable
    e_full = full.chute_altitude - quarter.chute_altitude
    e_half = half.chute_altitude - quarter.chute_altitude
    # y_h - y_h/4 = E (1 - 1/256), y_h/2 - y_h/4 = E (1/16 - 1/256): ratio 16.9 for a fourth-order method
    assert 10.0 < e_full / e_half < 25.0
    ref_h, ref_v = reference(r0, v0, mass)
    richardson = abs(full.chute_altitude - half.chute_altitude) * 16 / 15
    assert abs(full.chute_altitude - ref_h) <= 2 * richardson + 1e-3  # 1 mm: RK45's own error at rtol 1e-10
    assert full.chute_speed == pytest.approx(ref_v, rel=1e-6)


def test_a_periapsis_above_the_capture_skips():
    r0, v0 = _after_burn(200e3, 150e3)  # grazes the thin top of the atmosphere and climbs out again
    e = fly_entry(r0, v0, 195.0, VEHICLE)
    assert not e.captured and not e.survivable
    assert math.isnan(e.chute_altitude)


def test_a_steep_slow_fall_reaches_the_ground_only_when_the_chute_never_may_open():
    # 50 m above the ground, 600 m/s straight down: over the chute's speed limit all the way
    e = fly_entry(np.array([R + 50.0, 0.0, 0.0]), np.array([-600.0, 0.0, 0.0]), 190.0, VEHICLE)
    assert e.captured and not e.survivable
