"""The de-orbit plan on a navigated state: an apoapsis the navigation error alone could make is not
waited for (the burn starts after the slew), a true one well beyond the error still is, and on the
truth (no navigation error) the test is the 1 km one."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.deorbit import DeorbitController
from lander_autopilot.guidance.deorbit import (
    CIRCULAR_ORBIT,
    NAVIGATION_SIGMAS,
    START_SLACK,
    EntryVehicle,
    Orbit,
    circular_tolerance,
    plan,
)
from lander_sim.physics import constants as c
from lander_sim.physics.state import StateView
from lander_sim.scenes.vehicles import lander

VEHICLE = EntryVehicle(axial_thrust=4 * c.LANDER_MAX_THRUST * math.cos(math.atan(0.25)),
                       fuel_rate=4 * c.LANDER_FUEL_RATE)
GM, R = c.GM_MARS, c.MARS_RADIUS
A = 1.2 * R  # scenario 0's orbit
V = math.sqrt(GM / A)
SIGMA_V, SIGMA_R = 0.5, 10.0  # the navigation filter's initial errors per axis (m/s, m)
SLEW = 60.0
# the circular state: radial x, along-track -y, normal z
POS, VEL = np.array([A, 0.0, 0.0]), np.array([0.0, -V, 0.0])
RADIAL, ALONG, NORMAL = np.array([1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])


def _split(position_W: np.ndarray, velocity_W: np.ndarray) -> float:
    o = Orbit.of(position_W, velocity_W)
    return o.apoapsis_radius - o.periapsis_radius


def test_the_tolerance_is_the_split_the_errors_make():
    """First order: a tangential velocity error dv splits the apsides by 4 a dv / v, a radial one by
    2 a dv / v, a radial position error dr by 2 dr; the second-order remainder is O(dv / v) of it."""
    dv, dr = 1.5, 30.0
    assert _split(POS, VEL + dv * ALONG) == pytest.approx(4 * A * dv / V, rel=10 * dv / V)
    assert _split(POS, VEL + dv * RADIAL) == pytest.approx(2 * A * dv / V, rel=10 * dv / V)
    assert _split(POS + dr * RADIAL, VEL) == pytest.approx(2 * dr, rel=10 * dr / A)
    assert _split(POS, VEL + dv * NORMAL) < 1e-3 * 4 * A * dv / V  # a plane change, no eccentricity to first order
    # the components at right angles: an along-track and a radial velocity error add in quadrature
    assert _split(POS, VEL + dv * (ALONG + RADIAL)) == pytest.approx(2 * A * math.sqrt(5) * dv / V, rel=10 * dv / V)
    # the tolerance is that split at k sigma on every axis at once, the worst signs
    k = NAVIGATION_SIGMAS
    corner = _split(POS + k * SIGMA_R * RADIAL, VEL + k * SIGMA_V * (ALONG + RADIAL + NORMAL))
    assert circular_tolerance(A, SIGMA_V, SIGMA_R) == pytest.approx(corner, rel=10 * k * SIGMA_V / V)
    # the truth's test is the 1 km one, and no navigation error lowers it below that
    assert circular_tolerance(A) == CIRCULAR_ORBIT
    assert circular_tolerance(A, 1e-6, 1e-3) == CIRCULAR_ORBIT


# k sigma per axis just under the tolerance's k, each direction the error can take
ERRORS = {
    "along": (0.97 * NAVIGATION_SIGMAS * SIGMA_V * ALONG, 0.97 * NAVIGATION_SIGMAS * SIGMA_R * RADIAL),
    "against": (-0.97 * NAVIGATION_SIGMAS * SIGMA_V * ALONG, -0.97 * NAVIGATION_SIGMAS * SIGMA_R * RADIAL),
    "radial": (0.97 * NAVIGATION_SIGMAS * SIGMA_V * RADIAL, np.zeros(3)),
    "every axis": (0.97 * NAVIGATION_SIGMAS * SIGMA_V * (ALONG + RADIAL + NORMAL),
                   0.97 * NAVIGATION_SIGMAS * SIGMA_R * (RADIAL + ALONG + NORMAL)),
}


@pytest.mark.parametrize("name", list(ERRORS))
def test_a_circular_orbit_seen_through_the_error_burns_after_the_slew(name):
    dv_W, dr_W = ERRORS[name]
    pos, vel = POS + dr_W, VEL + dv_W
    assert _split(pos, vel) > 2 * CIRCULAR_ORBIT  # on the 1 km test alone an apoapsis would be waited for
    p = plan(pos, vel, 200.0, VEHICLE, slew_time=SLEW, velocity_sigma=SIGMA_V, position_sigma=SIGMA_R)
    # after the slew (to the plan's slack): within a second of it (the burn is centred half a burn on; its length from the
    # state there differs by a fraction of a second from the first guess's)
    assert SLEW - START_SLACK <= p.burn_start < SLEW + 1.0
    truth_test = plan(pos, vel, 200.0, VEHICLE, slew_time=SLEW)
    assert truth_test.burn_start > SLEW + 60.0  # the same state on the truth's test waits for its apoapsis


def test_an_elliptic_orbit_beyond_the_error_still_waits_for_its_apoapsis():
    """Apsides 20 km apart (2.4 times the 3-sigma split of 0.5 m/s and 10 m) from periapsis: the burn
    is centred on the apoapsis, half a period on, even flown with the navigation's sigmas."""
    rp, ra = A - 10e3, A + 10e3
    a = (rp + ra) / 2
    assert ra - rp > 2.3 * circular_tolerance(a, SIGMA_V, SIGMA_R)
    pos, vel = np.array([rp, 0.0, 0.0]), np.array([0.0, -math.sqrt(GM * (2 / rp - 1 / a)), 0.0])  # vis-viva
    p = plan(pos, vel, 200.0, VEHICLE, slew_time=SLEW, velocity_sigma=SIGMA_V, position_sigma=SIGMA_R)
    half_period = math.pi * math.sqrt(a**3 / GM)
    assert p.burn_start + p.burn_duration / 2 == pytest.approx(half_period, abs=1e-6)


def test_the_law_plans_with_its_navigation_sigmas():
    """The controller's ``navigation_velocity_sigma`` and ``navigation_position_sigma`` reach the plan
    made at its first step; the defaults (0) are the truth's test."""
    dv_W, dr_W = ERRORS["along"]
    q = np.array([math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0])
    state = StateView(t=0.0, r_W=POS + dr_W, v_W=VEL + dv_W, q=q, euler=np.zeros(3), omega_B=np.zeros(3), fuel=100.0)
    navigated = DeorbitController(lander("canted"), navigation_velocity_sigma=SIGMA_V, navigation_position_sigma=SIGMA_R)
    navigated.update(0.0, state, Demand(altitude=500.0))
    assert navigated.plan is not None and SLEW - START_SLACK <= navigated.plan.burn_start < SLEW + 1.0
    on_truth = DeorbitController(lander("canted"))
    on_truth.update(0.0, state, Demand(altitude=500.0))
    assert on_truth.plan is not None and on_truth.plan.burn_start > SLEW + 60.0
