"""Landing with a thruster that fails under the parachute: canopy torque model, probe burns, the
spinning descent (core-only: Simulation + landing law at 10 Hz, no ROS)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from lander_autopilot.controllers import make_controller
from lander_autopilot.controllers.base import REQUEST_DEPLOY_PARACHUTE, Demand
from lander_autopilot.controllers.failure import ChuteTorqueModel, SpinAllocation
from lander_sim.physics.events import EventKind
from lander_sim.physics.models import ChuteStatus
from lander_sim.physics.rotation import axis_angle_to_quat, quat_mult
from lander_sim.physics.state import StateView
from lander_sim.scenes import load_scene
from lander_sim.scenes.loader import ThrusterFailure
from lander_sim.simulation import Simulation

PERIOD = 0.1  # s: the scenes' dt, control at every step (10 Hz)


def fly(scene, controller, t_end=400.0):
    """Fly ``scene`` to touchdown; returns the touchdown event and the largest |spin| [rad/s] seen."""
    sim = Simulation(scene)
    spin = 0.0
    for k in range(round(t_end / PERIOD)):
        st = sim.state()
        spin = max(spin, abs(float(st.omega_B[2])))
        out = controller.update(k * PERIOD, st, Demand(altitude=0.0))
        if any(r.kind == REQUEST_DEPLOY_PARACHUTE for r in out.requests):
            sim.deploy_parachute()
        sim.set_throttles(out.throttles)
        sim.step(1)
        for e in sim.drain_events():
            if e.kind in (EventKind.LANDED, EventKind.HARD_LANDING, EventKind.CRASHED):
                return e, spin
    raise AssertionError("no touchdown")


def test_chute_torque_model_is_the_simulators_canopy():
    # The law's model and the simulator's canopy are the same formula (drag at the attachment
    # point, air velocity including the body rate): equal to round-off at any state and wind.
    scene = load_scene("landing")
    sim = Simulation(scene)
    chute = sim.dynamics.model("parachute")
    chute.status = ChuteStatus.DEPLOYED
    model = ChuteTorqueModel(scene.vehicle)
    rng = np.random.default_rng(3)
    for _ in range(20):
        y = scene.initial_state.copy()
        y[0:3] *= 1.0 - rng.uniform(0.0, 2e-3)  # 0 to 6.8 km lower
        y[3:6] = rng.normal(0.0, 20.0, 3)
        y[6:10] = quat_mult(y[6:10], axis_angle_to_quat(rng.normal(size=3), rng.uniform(0.0, 0.5)))
        y[10:13] = rng.normal(0.0, 0.3, 3)
        wind = rng.normal(0.0, 3.0, 3)
        sim.inputs.wind_W[:] = wind
        ctx = sim.dynamics.fill_context(y)
        truth = np.zeros(3)
        chute.add(ctx, np.zeros(3), np.zeros(3), truth)
        model.wind_W = wind
        st = StateView(0.0, y[0:3], y[3:6], y[6:10], np.zeros(3), y[10:13], float(y[13]))
        assert model.torque(st) == pytest.approx(truth, rel=1e-9, abs=1e-9 * max(1.0, float(np.abs(truth).max())))
        assert truth[2] == pytest.approx(0.0, abs=1e-9)  # no yaw: the canopy pulls on the body axis


@pytest.mark.parametrize("failed", range(4))
def test_spin_allocation_is_exact_and_keeps_the_lone_thruster_under_its_cap(failed):
    vehicle = load_scene("landing").vehicle
    a = SpinAllocation(vehicle, failed)
    assert failed not in a.working and a.lone not in a.pair
    T = vehicle.thrusters[0].max_thrust
    cos_cant = -vehicle.thrusters[0].direction_B[2]
    # Zero yaw torque needs the lone throttle equal to the sum of the pair's: at most lone 1 and the
    # pair 1/2 each, i.e. the lift of two whole thrusters; all three at full give three.
    assert a.max_lift_no_yaw == pytest.approx(2 * cos_cant * T, rel=1e-12)
    assert a.max_lift == pytest.approx(3 * cos_cant * T, rel=1e-12)
    u_true = np.zeros(4)
    u_true[a.working] = (0.6, 0.3, 0.8)
    tp, lift, yaw = float(u_true @ a.tau[:, :2] @ a.e_P), float(u_true @ a.fz), float(u_true @ a.tau[:, 2])
    u, sat = a.allocate(tp, lift, yaw)
    assert not sat and u[failed] == 0.0
    assert u == pytest.approx(u_true, abs=1e-12)  # three equations, three throttles
    u, sat = a.allocate(tp, lift, yaw, lone_max=0.2)
    assert sat and u[a.lone] <= 0.2 + 1e-12
    assert float(u @ a.fz) == pytest.approx(lift, rel=1e-12)  # the yaw gave way, not the lift


def test_a_failure_in_the_coast_under_the_canopy_is_found_by_the_probe_burns():
    # Coasting under the canopy the thrusters rest, so a dead one shows nothing; below probe_height
    # a probe burn every probe_period s shows its missing torque (the canopy's modelled).
    scene = replace(load_scene("landing"), thruster_failures=(ThrusterFailure(1, 60.0),))
    ctrl = make_controller("landing", scene.vehicle)
    sim = Simulation(scene)
    for k in range(round(400.0 / PERIOD)):
        st = sim.state()
        mode_before = ctrl.mode
        out = ctrl.update(k * PERIOD, st, Demand(altitude=0.0))
        if out.requests:
            sim.deploy_parachute()
        if ctrl.failure_detector.failed is not None:
            break
        sim.set_throttles(out.throttles)
        sim.step(1)
    assert ctrl.failure_detector.failed == 1
    h_c = float(np.linalg.norm(st.r_W)) - 3386e3 - 0.5
    assert mode_before == "coast" and ctrl.chute_requested
    # Found within one probe period of reaching probe_height (at ~44 m/s, 88 m per period).
    assert ctrl.probe_height - 2 * 44.0 * ctrl.probe_period < h_c <= ctrl.probe_height
    assert ctrl.spin is not None and ctrl.spin.lone == 3


@pytest.mark.parametrize("failed", range(4))
def test_scenario_1_with_a_thruster_dead_under_the_canopy_lands_spinning_within_the_limits(failed):
    # With one canted thruster out the lift without roll/pitch torque (the pair's, ~725 N) barely
    # holds the weight and spins the lander up at ~1.4 rad/s^2: ~30 s of braking from the canopy's
    # ~40 m/s would end at ~40 rad/s. Spinning at ~10 rad/s the lone thruster also lifts and its
    # torque only cones the axis; the sweep's limits must hold.
    scene = replace(load_scene("landing"), thruster_failures=(ThrusterFailure(failed, 100.0),))
    ctrl = make_controller("landing", scene.vehicle)
    td, spin = fly(scene, ctrl)
    assert ctrl.failure_detector.failed == failed
    v = td.values
    assert td.kind is EventKind.LANDED, td.detail
    assert v["descent_rate"] < 0.5 and v["ground_speed"] < 0.2 and v["tilt_deg"] < 5.0
    assert ctrl.SPIN_MIN < spin <= ctrl.SPIN_MAX + 1.0  # spun, and held under the simulator's limit


def test_the_probe_burns_cost_little_fuel_in_a_nominal_landing():
    # ~0.3 s at +0.25 throttle on four 0.5 kg/s thrusters every 2 s below 2000 m: ~0.15 kg a probe,
    # ~18 probes down to the braking at ~500 m; the landing itself is unchanged (same touchdown).
    scene = load_scene("landing")
    with_probes = make_controller("landing", scene.vehicle)
    without = make_controller("landing", scene.vehicle, probe_height=0.0)
    a, _ = fly(scene, with_probes)
    b, _ = fly(scene, without)
    assert a.kind is b.kind is EventKind.LANDED
    cost = b.values["fuel_left"] - a.values["fuel_left"]
    per_probe = 4 * 0.5 * 0.25 * 0.3
    n_probes = (2000.0 - 500.0) / 44.0 / 2.0
    assert 0.0 < cost < 2.0 * per_probe * n_probes, cost
    assert math.isfinite(a.values["tilt_deg"]) and a.values["tilt_deg"] < 5.0
