"""The end of the de-orbit's powered descent (the dispersed sweeps' fuel): the braking counts only on
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
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.rotation import matrix_to_quat
from lander_sim.physics.state import StateView
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


def test_mpc_last_braking_command_stops_the_fall_within_its_period_not_into_a_climb():
    from types import SimpleNamespace

    from lander_autopilot.controllers.deorbit_mpc import DeorbitMpcController
    from lander_autopilot.guidance.fuel_optimal import DragModel

    vehicle = lander("canted")
    ctrl = DeorbitMpcController(vehicle)
    ctrl.reset()
    drag = DragModel(k=20.0, surface_density=0.02, scale_height=11100.0, wind_L=(1.0, 0.0, 0.5))
    part = ctrl.mpc_descent  # the MPC's powered-descent part
    part.mpc = SimpleNamespace(drag=drag)  # the plan's drag model is all the cap reads of the QP
    mass, h, dt = vehicle.mass(50.0), 500.0, ctrl.settings.hold_time
    r_W = np.array([0.0, 0.0, c.MARS_RADIUS + h])
    g = c.GM_MARS / float(r_W @ r_W)
    v_L = np.array([0.3, -0.1, -0.25])  # 0.25 m/s still to stop
    axis = np.array([0.1, 0.0, 1.0]) / math.hypot(0.1, 1.0)  # the thrust axis flown (tilted)
    asked = 2.0 * mass * g * axis  # the QP's last braking command: ~g over the weight, 0.37 m/s in 0.1 s
    T = part.stop_within_period(asked, mass, h, v_L, float(axis[2]), r_W)
    # flown along the axis for one period, the vertical speed ends at rest, not climbing
    drag_up = float(drag.acceleration(np.array([[0.0, 0.0, h]]), v_L[None, :], np.array([mass]))[0, 2])
    v_end = v_L[2] + dt * (float(np.linalg.norm(T)) * axis[2] / mass - g + drag_up)
    assert v_end == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(T / np.linalg.norm(T), axis, rtol=0, atol=1e-15)  # its direction kept
    # a command that does not reverse the fall, or a lander already climbing: unchanged
    gentle = 0.9 * mass * g * axis
    assert part.stop_within_period(gentle, mass, h, v_L, float(axis[2]), r_W) is gentle
    assert part.stop_within_period(asked, mass, h, np.array([0.0, 0.0, 0.1]), float(axis[2]), r_W) is asked


def test_braking_limb_runs_on_the_collective_left():
    vehicle = lander("canted")
    law = DeorbitController(vehicle).descent
    mass, g = vehicle.mass(40.0), 3.7
    full = law.braking_acceleration(mass, g)
    law.headroom.share = 0.08
    assert law.braking_acceleration(mass, g) == pytest.approx(law.law.brake_fraction * (0.92 * law.law.T_v / mass - g))
    assert law.braking_acceleration(mass, g) < full


def test_braking_limb_ends_at_rest_inside_the_band_above_the_floor():
    """The limb's descent-rate demand is 0 at ``floor + stop_above`` (inside the 2 m band), and climbs back under it."""
    law = DeorbitController(lander("canted")).descent
    law.floor, law.law.mode = DEMAND.altitude, "braking"
    stop = DEMAND.altitude + law.stop_above
    assert 0.0 < law.stop_above < 2.0
    r = c.MARS_RADIUS + stop
    g = c.GM_MARS / (r * r)
    # at rest at the limb's end: gravity alone is asked for (no velocity error, no deceleration fed forward)
    assert law.vertical_acceleration(0.0, stop, 0.0, DEMAND) == pytest.approx(g, rel=1e-12)
    # half a metre under it, at rest: a climb is asked for (RETURN_RATE per metre); above it, a descent
    assert law.vertical_acceleration(0.0, stop - 0.5, 0.0, DEMAND) > g
    assert law.vertical_acceleration(0.0, stop + 5.0, 0.0, DEMAND) < g


def test_axis_bias_integrates_what_the_attitude_law_flies_short_and_is_bounded():
    """Integral action on the thrust axis while braking (DescentToAltitude.axis_bias): a steady
    shortfall of the axis flown grows the correction at ``shortfall / axis_time`` a second, up to
    ``axis_limit``; none while coasting."""
    law = DeorbitController(lander("canted")).descent
    L = np.eye(3)  # local ENU axes (rows) in world coordinates: here the world's own
    tilt = 0.05  # the axis flown: 0.05 rad toward east (rows: body axes in world coordinates)
    R = np.array([[math.cos(tilt), 0.0, -math.sin(tilt)], [0.0, 1.0, 0.0], [math.sin(tilt), 0.0, math.cos(tilt)]])
    q = matrix_to_quat(R)
    state = StateView(t=0.0, r_W=np.array([0.0, 0.0, c.MARS_RADIUS + 500.0]), v_W=np.zeros(3), q=q,
                      euler=np.zeros(3), omega_B=np.zeros(3), fuel=40.0)
    flown = math.tan(tilt)
    wanted = np.array([0.1, -0.02])
    law.floor, law.law.mode = DEMAND.altitude, "coast"
    assert law.axis_bias(0.0, state, L, wanted) is None
    law.law.mode = "braking"
    assert np.array_equal(law.axis_bias(0.0, state, L, wanted), np.zeros(2))  # no history yet
    bias = law.axis_bias(0.1, state, L, wanted)
    expected = 0.1 / law.axis_time * (wanted - np.array([flown, 0.0]))
    assert bias == pytest.approx(expected, rel=1e-9)
    for k in range(2, 200):
        bias = law.axis_bias(0.1 * k, state, L, wanted)
    assert float(np.linalg.norm(bias)) == pytest.approx(law.axis_limit, rel=1e-12)
    law.law.mode = "coast"
    assert law.axis_bias(20.0, state, L, wanted) is None


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


def test_hover_capture_keeps_the_climb_rate_inside_the_band_under_what_the_drift_leaves():
    """Inside the band the climb rate allowed shrinks with the ground speed, so the total speed keeps
    under ``AT_REST * speed``: at 0.18 m/s of drift (a dispersed flight from 200 km began its hover so) the law holds the
    altitude instead of descending at 0.1 m/s, 0.21 m/s in all, outside the band's speed."""
    capture = HoverCapture(lander("canted"))
    capture.band, capture.speed = 2.0, 0.2
    h = DEMAND.altitude + 1.0
    r = c.MARS_RADIUS + h
    g = c.GM_MARS / (r * r)
    # still air, at rest: the approach at APPROACH * speed (0.1 m/s) toward the demand
    capture.law.v_local = np.zeros(3)
    assert capture.vertical_acceleration(0.0, h, 0.0, DEMAND) == pytest.approx(
        g + capture.RATE_GAIN * (-capture.APPROACH * capture.speed), rel=1e-12)
    # 0.12 m/s of drift: what is left of AT_REST * speed (0.16 m/s), sqrt(0.16^2 - 0.12^2) ~ 0.106, caps
    # nothing yet; at 0.15 m/s it caps the approach at sqrt(0.16^2 - 0.15^2) ~ 0.056 m/s
    capture.law.v_local = np.array([0.09, -0.12, 0.0])  # ENU, 0.15 m/s
    allowed = math.sqrt((capture.AT_REST * capture.speed) ** 2 - 0.15**2)
    assert capture.vertical_acceleration(0.0, h, 0.0, DEMAND) == pytest.approx(g - capture.RATE_GAIN * allowed, rel=1e-9)
    # 0.18 m/s: nothing left, the climb rate is brought to zero where it is
    capture.law.v_local = np.array([0.0, -0.18, 0.0])
    assert capture.vertical_acceleration(0.0, h, -0.16, DEMAND) == pytest.approx(g + capture.RATE_GAIN * 0.16, rel=1e-12)


def test_hover_takes_over_the_wind_from_the_braking():
    """At the handover the hover's horizontal loop starts holding against the drag at rest in the
    wind the braking planned on (its integral preset), not from zero."""
    controller = DeorbitController(lander("canted"))
    law, hover = controller.descent, controller.hover
    law.drag_k, law.law.mass = 20.0, 700.0  # chute out: sum 1/2 Cd A [m^2], mass [kg]
    law.drift_W = np.array([0.0, -5.0, 0.0])  # no air fitted: the drift is the wind (world = ENU here)
    L = np.eye(3)
    h = 500.0
    drag = law.horizontal_drag(L, h, np.zeros(3))
    # at rest in a wind toward -north the drag pushes toward -north, as 1/2 rho Cd A w^2 / m
    assert drag == pytest.approx([0.0, -20.0 * MARS_ATMOSPHERE.density(h) / 700.0 * 25.0], rel=1e-12)
    state = StateView(t=0.0, r_W=np.array([0.0, 0.0, c.MARS_RADIUS + h]), v_W=np.zeros(3), q=np.array([1.0, 0.0, 0.0, 0.0]),
                      euler=np.zeros(3), omega_B=np.zeros(3), fuel=40.0)
    assert np.array_equal(hover.law.horizontal_acceleration(state, L, h, np.zeros(3), np.zeros(2)), np.zeros(2))
    hover.take_over(drag)
    # no velocity error: the thrust's horizontal acceleration asked for is the drag's opposite
    assert hover.law.horizontal_acceleration(state, L, h, np.zeros(3), np.zeros(2)) == pytest.approx(-drag, rel=1e-12)
