"""Ground-speed and landing laws flown core-only (Simulation + controller at 10 Hz, no ROS)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from lander_autopilot.controllers import make_controller
from lander_autopilot.controllers.base import (
    REQUEST_DEPLOY_PARACHUTE,
    REQUEST_LANDING_UNREACHABLE,
    ControllerError,
    Demand,
    DemandError,
)
from lander_autopilot.design.translational import local_frame
from lander_sim.physics.constants import MARS_RADIUS, SURFACE_GRAVITY
from lander_sim.physics.events import EventKind
from lander_sim.physics.models.ground import TouchdownLimits
from lander_sim.scenes import load_scene
from lander_sim.scenes.loader import SceneError, parse_scene
from lander_sim.simulation import Simulation

PERIOD = 0.1  # s: the scenes' dt, control at every step (10 Hz)


def fly(scene, controller, demand_at, t_end, wind=None, on_request=None):
    """Fly ``scene`` with ``controller``; ``demand_at(t)`` gives the demand. Returns samples and events."""
    sim = Simulation(scene)
    if wind is not None:
        sim.set_wind(wind)
    rows, events, requests, modes = [], [], [], []
    for k in range(round(t_end / PERIOD)):
        st = sim.state()
        t = k * PERIOD
        L = local_frame(st.r_W)
        v = L @ st.v_W
        rows.append((t, float(np.linalg.norm(st.r_W)) - MARS_RADIUS, v[0], v[1], v[2], st.fuel))
        out = controller.update(t, st, demand_at(t))
        for r in out.requests:
            requests.append((t, r))
            if r.kind == REQUEST_DEPLOY_PARACHUTE:
                sim.deploy_parachute()
        if out.mode is not None and (not modes or modes[-1] != out.mode):
            modes.append(out.mode)
        sim.set_throttles(out.throttles)
        sim.step(1)
        events += sim.drain_events()
        if sim.phase.name != "FLYING":
            break
    return np.array(rows), events, requests, modes


def touchdown(events):
    return next(e for e in events if e.kind in (EventKind.LANDED, EventKind.HARD_LANDING, EventKind.CRASHED))


# --- ground speed ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def gs_scene():
    return load_scene("ground-speed")


def test_ground_speed_from_50_m_s_to_rest_within_30_s_holding_altitude(gs_scene):
    ctrl = make_controller("ground-speed", gs_scene.vehicle)
    rows, events, _, _ = fly(gs_scene, ctrl, lambda t: Demand(altitude=500.0), 40.0)
    t, h, gs = rows[:, 0], rows[:, 1], np.hypot(rows[:, 2], rows[:, 3])
    assert gs[0] == pytest.approx(50.0)
    above = np.nonzero(gs >= 0.2)[0]
    t_settle = t[above[-1] + 1]
    assert t_settle < 30.0, f"ground speed below 0.2 m/s for good only from t = {t_settle} s"
    assert np.abs(h - 500.0).max() < 5.0
    assert not events


def test_steady_wind_leaves_no_steady_ground_speed_error(gs_scene):
    # 10 m/s east wind on a lander at rest: its drag (~2.7 N, 0.013 m/s^2) is a constant
    # disturbance; the integral term must cancel it (a P-only outer loop would leave
    # a / k_p ~ 0.014 m/s, the integral removes even that).
    scene = replace(gs_scene, initial_state=gs_scene.initial_state.copy())
    scene.initial_state[3:6] = 0.0
    ctrl = make_controller("ground-speed", scene.vehicle)
    rows, _, _, _ = fly(scene, ctrl, lambda t: Demand(altitude=500.0), 60.0, wind=[10.0, 0.0, 0.0])
    last = rows[:, 0] >= 50.0
    err = np.hypot(rows[last, 2], rows[last, 3])
    assert err.max() < 0.05
    assert abs(ctrl.velocity_integral[0]) > 0.0  # the integrator carries the wind's drag


def test_demand_velocity_is_tracked(gs_scene):
    scene = replace(gs_scene, initial_state=gs_scene.initial_state.copy())
    scene.initial_state[3:6] = 0.0
    ctrl = make_controller("ground-speed", scene.vehicle)
    rows, _, _, _ = fly(scene, ctrl, lambda t: Demand(altitude=500.0, velocity=(3.0, -4.0) if t >= 5.0 else None), 40.0)
    end = rows[-1]
    assert end[2] == pytest.approx(3.0, abs=0.02) and end[3] == pytest.approx(-4.0, abs=0.02)
    assert rows[49, 2] == pytest.approx(0.0, abs=1e-6)  # nothing asked before t = 5 s


@pytest.mark.parametrize("bad", [(float("nan"), 0.0), (float("inf"), 1.0), (300.0, 0.0), (1.0,), "fast"])
def test_bad_demand_velocity_is_refused_with_a_message(bad):
    with pytest.raises(DemandError, match="demand velocity"):
        Demand(velocity=bad)


def test_bad_parameters_name_the_parameter(gs_scene):
    with pytest.raises(ControllerError, match="max_tilt"):
        make_controller("ground-speed", gs_scene.vehicle, max_tilt=2.0)
    with pytest.raises(ControllerError, match="brake_fraction"):
        make_controller("landing", gs_scene.vehicle, brake_fraction=1.5)


# --- landing -----------------------------------------------------------------------------------


def test_landing_from_hover_touches_down_inside_the_limits():
    scene = load_scene("landing-hover")
    ctrl = make_controller("landing", scene.vehicle)
    rows, events, requests, modes = fly(scene, ctrl, lambda t: Demand(altitude=0.0), 120.0)
    td = touchdown(events)
    assert td.kind is EventKind.LANDED
    assert td.values["descent_rate"] < 0.5 and td.values["ground_speed"] < 0.2 and td.values["tilt_deg"] < 5.0
    # The flare limb ends at v_td = 0.25 m/s at contact; the 10 Hz loop lags it by little.
    assert td.values["descent_rate"] == pytest.approx(ctrl.v_td, abs=0.05)
    assert modes == ["coast", "braking", "flare"]
    assert not requests  # 500 m is below chute_min_altitude, and the fuel suffices
    assert td.values["fuel_left"] == pytest.approx(rows[-1, 5], abs=0.1)


def test_scenario_1_lands_with_the_parachute():
    scene = load_scene("landing")
    ctrl = make_controller("landing", scene.vehicle)
    _, events, requests, modes = fly(scene, ctrl, lambda t: Demand(altitude=0.0), 400.0)
    td = touchdown(events)
    assert td.kind is EventKind.LANDED, td.detail
    assert td.values["descent_rate"] < 0.5 and td.values["ground_speed"] < 0.2 and td.values["tilt_deg"] < 5.0
    kinds = [r.kind for _, r in requests]
    assert kinds == [REQUEST_DEPLOY_PARACHUTE]
    assert any(e.kind is EventKind.PARACHUTE_DEPLOYED for e in events)
    assert modes == ["coast", "braking", "flare"]


def test_unreachable_landing_is_reported_once():
    scene = load_scene("landing-hover")
    y0 = scene.initial_state.copy()
    y0[13] = 8.0  # kg: a landing from 500 m needs about 30
    scene = replace(scene, initial_state=y0)
    ctrl = make_controller("landing", scene.vehicle)
    _, events, requests, _ = fly(scene, ctrl, lambda t: Demand(altitude=0.0), 60.0)
    unreachable = [r for _, r in requests if r.kind == REQUEST_LANDING_UNREACHABLE]
    assert len(unreachable) == 1
    vals = dict(unreachable[0].values)
    assert vals["fuel_needed"] > vals["fuel_left"] == 8.0
    assert touchdown(events).kind is not EventKind.LANDED  # it was right


def test_fuel_estimate_matches_a_nominal_landing():
    # From 500 m at rest the estimate (no drag, ideal profile) and the fuel a flight really burns
    # agree to the drag and attitude-control overheads, a few percent.
    scene = load_scene("landing-hover")
    ctrl = make_controller("landing", scene.vehicle)
    need = ctrl.fuel_needed(500.0, 0.0, scene.vehicle.mass(100.0), chute=False)
    _, events, _, _ = fly(scene, ctrl, lambda t: Demand(altitude=0.0), 120.0)
    used = 100.0 - touchdown(events).values["fuel_left"]
    assert need == pytest.approx(used, rel=0.1)


# --- touchdown classification --------------------------------------------------------------------


def test_touchdown_limits_classify_safe_hard_crash():
    lim = TouchdownLimits(1.0, 1.0, math.radians(10), 3.0, 3.0, math.radians(30))
    assert lim.classify(0.5, 0.5, 0.0) == "safe"
    assert lim.classify(2.0, 0.5, 0.0) == "hard"
    assert lim.classify(0.5, 0.5, math.radians(20)) == "hard"
    assert lim.classify(0.5, 3.5, 0.0) == "crash"


@pytest.mark.parametrize("drop, kind", [(0.05, EventKind.LANDED), (0.5, EventKind.HARD_LANDING), (2.0, EventKind.CRASHED)])
def test_simulation_classifies_a_free_fall_touchdown(drop, kind):
    # Free fall from `drop` m above contact: v = sqrt(2 g drop) = 0.6, 1.9, 3.9 m/s against the
    # scene's limits (safe 1 m/s, crash 3 m/s).
    scene = load_scene("descent-10km-canted")
    y0 = scene.initial_state.copy()
    y0[1] = -(MARS_RADIUS + 0.5 + drop)
    sim = Simulation(replace(scene, initial_state=y0))
    sim.advance_to(5.0)
    ev = [e for e in sim.drain_events() if e.kind in (EventKind.LANDED, EventKind.HARD_LANDING, EventKind.CRASHED)]
    assert [e.kind for e in ev] == [kind]
    v = ev[0].values
    # The rate is interpolated inside the last step, where the true one also lies: within g dt.
    v_exact = math.sqrt(2 * SURFACE_GRAVITY * drop)
    assert v["descent_rate"] == pytest.approx(v_exact, abs=SURFACE_GRAVITY * scene.dt)
    assert set(v) >= {"descent_rate", "ground_speed", "tilt_deg", "fuel_left"}


def test_scene_touchdown_section_errors_name_the_key():
    base = {"vehicle": {"preset": "lander"}, "initial": {"position_W": [0, -3390000.0, 0]}, "dt": 0.1,
            "models": {"gravity": {"kind": "inverse-square"}, "ground": {}}}
    with pytest.raises(SceneError, match=r"touchdown\.crash\.descent_rate: expected a number >= 2.0"):
        parse_scene({**base, "touchdown": {"safe": {"descent_rate": 2.0}, "crash": {"descent_rate": 1.0}}}, "t.yaml")
    with pytest.raises(SceneError, match=r"touchdown\.safe\.tilt: unknown key"):
        parse_scene({**base, "touchdown": {"safe": {"tilt": 5}}}, "t.yaml")
    with pytest.raises(SceneError, match=r"touchdown: needs the ground"):
        parse_scene({**base, "models": {"gravity": {"kind": "inverse-square"}}, "touchdown": {}}, "t.yaml")


def test_landing_sweep_outcome_follows_the_classification_and_the_sweep_limits():
    from lander_tools.sweep.metrics import Samples, evaluate
    from lander_tools.sweep.spec import EndCondition

    end = EndCondition(land=True, max_touchdown_descent_rate=0.5, max_touchdown_ground_speed=0.2,
                       max_touchdown_tilt=math.radians(5.0))

    def outcome(terminal, **td):
        s = Samples(t=np.array([0.0, 1.0]), altitude_error=np.zeros(2), tilt=np.zeros(2), body_rate=np.zeros(2),
                    fuel_start=100.0, fuel_end=90.0, saturated_updates=0, period=0.1, touchdown_speed=math.nan,
                    terminal=terminal, t_change=0.0, touchdown=td)
        out, ok, m = evaluate(s, end)
        return out, ok, m["touchdown_tilt"]

    good = {"descent_rate": 0.3, "ground_speed": 0.1, "tilt_deg": 2.0, "classification": "safe"}
    assert outcome("landed", **good) == ("landed", True, 2.0)
    assert outcome("landed", **{**good, "tilt_deg": 6.0})[:2] == ("over-limits", False)
    assert outcome("landed", **{**good, "descent_rate": 0.6})[:2] == ("over-limits", False)
    assert outcome("landed", **{**good, "classification": "hard"})[:2] == ("hard-landing", False)
    assert outcome("crashed", **{**good, "classification": "crash"})[:2] == ("crashed", False)
    assert outcome("ok")[:2] == ("no-touchdown", False)


def test_outer_loop_gains_are_the_closed_form_of_the_placed_poles(gs_scene):
    # [int e, e]' = [[0, 1], [0, 0]] x + [0, 1] a: s^2 + k_p s + k_i = (s - p1)(s - p2).
    ctrl = make_controller("ground-speed", gs_scene.vehicle, velocity_poles=(-0.3, -0.6))
    assert ctrl.k_i == pytest.approx(0.18, abs=1e-9) and ctrl.k_p == pytest.approx(0.9, abs=1e-9)
    q = make_controller("ground-speed", gs_scene.vehicle, velocity_lqr=(1.0, 1.0, 1.0))
    # LQR of a double integrator with Q = I, R = 1: k_i = 1, k_p = sqrt(3) (Riccati closed form).
    assert q.k_i == pytest.approx(1.0, abs=1e-9) and q.k_p == pytest.approx(math.sqrt(3.0), abs=1e-9)


# --- thruster failure ------------------------------------------------------------------------------


def _with_failure(scene_name, thruster, time):
    from lander_sim.scenes.loader import ThrusterFailure

    return replace(load_scene(scene_name), thruster_failures=(ThrusterFailure(thruster, time),))


@pytest.mark.parametrize("thruster", [0, 2])
def test_a_thruster_failure_is_detected_from_the_state_alone(thruster):
    # The law never reads the failure flags: it sees the missing torque in the body rates. A whole
    # thruster at the flare's half throttle is ~110 N m against a few N m of model error (2 %
    # thrust, 5 % inertia), so the right thruster is named within two control periods.
    scene = _with_failure("landing-hover", thruster, 30.0)
    ctrl = make_controller("landing", scene.vehicle)
    fly(scene, ctrl, lambda t: Demand(altitude=0.0), 120.0)
    assert ctrl.failure_detector.failed == thruster
    assert 30.0 < ctrl.failure_detector.failed_at <= 30.2 + 1e-9
    assert ctrl.allocation is not None and thruster not in ctrl.allocation.working


@pytest.mark.parametrize("scene_name", ["landing-hover", "landing"])
def test_no_failure_is_detected_in_a_nominal_landing(scene_name):
    ctrl = make_controller("landing", load_scene(scene_name).vehicle)
    _, events, _, _ = fly(load_scene(scene_name), ctrl, lambda t: Demand(altitude=0.0), 400.0)
    assert touchdown(events).kind is EventKind.LANDED
    assert ctrl.failure_detector.failed is None and ctrl.allocation is None


def test_three_thruster_allocation_holds_roll_and_pitch_exactly():
    scene = load_scene("landing-hover")
    from lander_autopilot.controllers.failure import ThreeThrusterAllocation

    for failed in range(4):
        a = ThreeThrusterAllocation(scene.vehicle, failed)
        u_true = np.zeros(4)
        u_true[a.working] = (0.55, 0.1, 0.7) if failed % 2 else (0.1, 0.55, 0.7)  # any reachable throttles
        torque, lift = u_true @ a.tau[:, :2], float(u_true @ a.fz)
        u, sat = a.allocate(torque, lift)
        assert u[failed] == 0.0 and not sat
        assert u == pytest.approx(u_true, abs=1e-9)  # three equations, three throttles: exact
        # A roll/pitch torque that needs the lone thruster below zero is out of reach: reported.
        _, sat = a.allocate(-torque * 5.0, lift)
        assert sat
        # Without roll or pitch torque only the diagonal pair opposite the lone thruster lifts.
        assert a.max_lift == pytest.approx(2 * 0.9701425 * scene.vehicle.thrusters[0].max_thrust)


@pytest.mark.xfail(strict=True, reason=(
    "not reached: with three canted thrusters the lift left with no roll/pitch torque is the diagonal "
    "pair's, ~725 N, against ~740 N weight at full tank, and the tilt rate built before detection can "
    "only be taken out once the yaw spin-up has turned the body; flown, this case lands hard "
    "(descent 0.29 m/s, ground speed 1.6 m/s, tilt 6.7 deg)"))
def test_landing_with_a_thruster_failed_mid_descent_touches_down_safely():
    scene = _with_failure("landing-hover", 0, 31.0)  # at about 10 m, in the flare
    ctrl = make_controller("landing", scene.vehicle)
    _, events, _, _ = fly(scene, ctrl, lambda t: Demand(altitude=0.0), 120.0)
    td = touchdown(events)
    assert td.values["descent_rate"] < 0.5 and td.values["ground_speed"] < 0.2 and td.values["tilt_deg"] < 5.0
