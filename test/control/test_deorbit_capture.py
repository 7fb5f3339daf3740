"""The end of the de-orbit's powered descent (issue 14's dispersed fuel): the braking counts only on
the collective the attitude law leaves it, and the hover captures the band without setting the
lander moving again. Core-only, fast."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.combined import CollectiveHeadroom, mix_with_attitude_priority
from lander_autopilot.controllers.deorbit import DeorbitController, HoverCapture
from lander_autopilot.controllers.ground_speed import GroundSpeedController
from lander_sim.physics import constants as c
from lander_sim.scenes.vehicles import lander

DEMAND = Demand(altitude=500.0)


def test_headroom_learns_the_attitude_share_only_where_the_collective_is_capped():
    d = np.array([0.08, -0.02, -0.08, 0.02])  # an attitude law's differential
    room = CollectiveHeadroom(time_constant=1.0)
    # the collective has room (0.6 + 0.08 < 1): the differential costs the braking nothing
    u = mix_with_attitude_priority(0.6, d)
    room.update(float(d.max()), float(u.max()) >= 1.0, 0.1)
    assert room.share == 0.0 and room.available == 1.0
    # capped (0.97 + 0.08 > 1): the mixer keeps the differential whole and lowers the collective to 0.92
    u = mix_with_attitude_priority(0.97, d)
    assert float(u.max()) == pytest.approx(1.0) and float(u.mean()) == pytest.approx(0.92)
    for _ in range(60):  # 6 s of 0.1 s periods: six time constants
        room.update(float(d.max()), True, 0.1)
    assert room.share == pytest.approx(0.08 * (1.0 - 0.9**60), rel=1e-12)  # first-order filter, alpha = dt / tau
    assert room.available == pytest.approx(1.0 - room.share)
    # a period without the cap holds what was learnt (the torque under the canopy is steady)
    held = room.share
    room.update(0.0, False, 0.1)
    assert room.share == held


def test_braking_limb_runs_on_the_collective_left():
    vehicle = lander("canted")
    law = DeorbitController(vehicle).descent
    mass, g = vehicle.mass(40.0), 3.7
    full = law.braking_acceleration(mass, g)
    law.headroom.share = 0.08
    assert law.braking_acceleration(mass, g) == pytest.approx(law.brake_fraction * (0.92 * law.T_v / mass - g))
    assert law.braking_acceleration(mass, g) < full


def _capture(law: GroundSpeedController, e0: float, t_end: float = 20.0, dt: float = 0.01) -> tuple[float, float]:
    """The law's vertical loop on a point mass from ``e0`` m off the demand at rest, thrust as asked:
    (first instant [s] within 2 m at under 0.2 m/s, largest climb rate [m/s] after it)."""
    h, hd, t, caught, after = DEMAND.altitude + e0, 0.0, 0.0, math.nan, 0.0
    while t < t_end:
        r = c.MARS_RADIUS + h
        hd += (law.vertical_acceleration(t, h, hd, DEMAND) - c.GM_MARS / (r * r)) * dt
        h += hd * dt
        t += dt
        if math.isnan(caught) and abs(h - DEMAND.altitude) <= 2.0 and abs(hd) <= 0.2:
            caught = t
        elif not math.isnan(caught):
            after = max(after, abs(hd))
    return caught, after


def test_hover_capture_is_at_rest_in_the_band_at_once_and_stays_so():
    vehicle = lander("canted")
    capture, plain = HoverCapture(vehicle), GroundSpeedController(vehicle)
    capture.band, capture.speed = 2.0, 0.2
    # at rest 1.5 m under the demand: caught at once, and never moved faster than the band's speed
    caught, after = _capture(capture, -1.5)
    assert caught <= 0.011 and after <= capture.APPROACH * capture.speed + 1e-9
    # the ground-speed law's own loop (eq 18) sets it moving at up to ~0.5 m/s: out of the band's speed
    _, after_plain = _capture(plain, -1.5)
    assert after_plain > 0.2
    # 6 m under (an MPC descent in the sweep's tail): into the band at rest sooner than eq 18 gets there
    caught, after = _capture(capture, -6.0)
    caught_plain, _ = _capture(plain, -6.0)
    assert after <= 0.2 and caught < caught_plain
    # and the braking curve's own bound: 4 m to the band at CAPTURE_ACCEL, twice the bang-bang time
    # with the rate loop's lag (1 / RATE_GAIN) on top
    assert caught < 2.0 * math.sqrt(4.0 / capture.CAPTURE_ACCEL) + 2.0 / capture.RATE_GAIN
