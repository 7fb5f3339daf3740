"""De-orbit planning: orbital elements, the burn's size and fuel against closed forms, a survivable entry."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.guidance.deorbit import EntryVehicle, Orbit, _propagate, fly_entry, plan
from lander_sim.physics import constants as c

# The canted lander flat out: exhaust (+-0.25, 0, -1) normalised, so the axial thrust is cos(atan 0.25) of it.
VEHICLE = EntryVehicle(axial_thrust=4 * c.LANDER_MAX_THRUST * math.cos(math.atan(0.25)),
                       fuel_rate=4 * c.LANDER_FUEL_RATE)
GM, R = c.GM_MARS, c.MARS_RADIUS


def _circular(r: float) -> tuple[np.ndarray, np.ndarray]:
    return np.array([r, 0.0, 0.0]), np.array([0.0, -math.sqrt(GM / r), 0.0])


def test_orbit_elements_of_an_ellipse_at_periapsis():
    rp, ra = R + 300e3, R + 2000e3
    a = (rp + ra) / 2
    vp = math.sqrt(GM * (2 / rp - 1 / a))  # vis-viva
    o = Orbit.of(np.array([0.0, rp, 0.0]), np.array([vp, 0.0, 0.0]))
    assert o.semi_major_axis == pytest.approx(a, rel=1e-12)
    assert o.periapsis_radius == pytest.approx(rp, rel=1e-12)
    assert o.apoapsis_radius == pytest.approx(ra, rel=1e-12)
    # from periapsis the apoapsis is half a period away
    assert o.time_to_apoapsis == pytest.approx(math.pi * math.sqrt(a**3 / GM), rel=1e-9)


@pytest.mark.parametrize("altitude", [0.2 * R, 200e3])
def test_plan_from_a_circular_orbit(altitude):
    r0 = R + altitude
    pos, vel = _circular(r0)
    p = plan(pos, vel, 200.0, VEHICLE, slew_time=60.0)
    # Size: the vis-viva speed change that puts the periapsis at the planned altitude (Hohmann's
    # first half), and the rocket equation's fuel for it.
    rp = R + p.periapsis_altitude
    dv = math.sqrt(GM / r0) * (1 - math.sqrt(2 * rp / (r0 + rp)))
    # (The plan reads the speed off a two-body propagation to the burn, rtol 1e-10: 3.5e-7 m/s of 3.5 km/s.)
    assert p.delta_v == pytest.approx(dv, abs=1e-6)
    assert p.fuel == pytest.approx(200.0 * (1 - math.exp(-p.delta_v / VEHICLE.exhaust_speed)), rel=1e-12)
    assert p.fuel_left == pytest.approx(100.0 - p.fuel)
    # Timing and direction: after the slew, centred half a burn later, thrust against the velocity.
    assert p.burn_start == pytest.approx(60.0)
    assert p.burn_duration == pytest.approx(p.fuel / VEHICLE.fuel_rate)
    r_c, v_c = _propagate(pos, vel, p.burn_start + p.burn_duration / 2, GM)
    assert float(p.direction_W @ v_c) / np.linalg.norm(v_c) == pytest.approx(-1.0, abs=1e-12)
    # The impulsive burn there gives the planned periapsis (two-body elements of the new state).
    after = Orbit.of(r_c, v_c + p.delta_v * p.direction_W)
    assert after.periapsis_radius == pytest.approx(rp, abs=1.0)
    # Survivable: one pass, the chute opens within its limits (speed and drag) above 3 km.
    e = p.entry
    assert e.captured and e.chute_altitude >= 3_000.0
    assert e.chute_speed <= VEHICLE.chute_max_speed
    rho = c.ATMOSPHERE_SURFACE_DENSITY * math.exp(-e.chute_altitude / c.ATMOSPHERE_SCALE_HEIGHT)
    assert 0.5 * rho * VEHICLE.chute_cd * VEHICLE.chute_area * e.chute_speed**2 <= VEHICLE.chute_max_drag * (1 + 1e-6)
    # The plan takes the highest (cheapest) survivable periapsis of those tried: 5 km higher is not.
    higher = p.periapsis_altitude + 5_000.0
    if R + higher < r0:
        v_new = math.sqrt(2 * GM * (R + higher) / (r0 * (r0 + higher + R)))
        m = 200.0 * math.exp(-(math.sqrt(GM / r0) - v_new) / VEHICLE.exhaust_speed)
        worse = fly_entry(r_c, v_c * (v_new / np.linalg.norm(v_c)), m, VEHICLE)
        assert not (worse.survivable and worse.chute_altitude >= 3_000.0)


def test_too_little_fuel_is_a_clear_error():
    pos, vel = _circular(0.2 * R + R)
    with pytest.raises(ValueError, match="no survivable single-burn de-orbit"):
        plan(pos, vel, 105.0, VEHICLE)  # 5 kg of fuel: about 18 m/s, the orbit needs over 100
