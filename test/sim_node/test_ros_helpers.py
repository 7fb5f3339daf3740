"""Pure tests of the node's helpers (no middleware): conventions, parameters, pacing, labels."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from lander_sim.physics import rotation
from lander_sim.ros import convert
from lander_sim.ros.config import PARAMETERS, ConfigError, check_parameter, check_params_file
from lander_sim.ros.pacing import Pacer, steps_per_tick

REPO_CONFIG = __import__("pathlib").Path(__file__).resolve().parents[2] / "config" / "sim.yaml"

unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(st.tuples(unit, unit, unit, unit).filter(lambda q: sum(x * x for x in q) > 1e-3), st.tuples(unit, unit, unit))
def test_ros_orientation_rotates_body_vectors_into_the_world_like_the_core(q, v_B):
    # Independent check of the convention: scipy's active rotation from ROS (x, y, z, w) must map a
    # body vector exactly where the core's R(q)^T (eq 13 transposed) puts it; 1e-12 is rounding.
    q = rotation.quat_normalise(np.array(q))
    ros = Rotation.from_quat(convert.ros_orientation(q))
    assert np.allclose(ros.apply(v_B), rotation.body_to_world(q, np.array(v_B)), atol=1e-12)


def test_odometry_twist_is_in_the_body_frame():
    # A lander yawed 90 deg about world z moving along world +x moves along body -y: REP 105 twist.
    q = rotation.axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), math.pi / 2)
    snap = SimpleNamespace(t=1.5, r_W=np.zeros(3), v_W=np.array([2.0, 0.0, 0.0]), q=q, omega_B=np.array([0.1, 0.2, 0.3]))
    v3 = lambda: SimpleNamespace(x=0.0, y=0.0, z=0.0)  # noqa: E731
    msg = SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=0, nanosec=0)),
        pose=SimpleNamespace(pose=SimpleNamespace(position=v3(), orientation=SimpleNamespace(x=0, y=0, z=0, w=0))),
        twist=SimpleNamespace(twist=SimpleNamespace(linear=v3(), angular=v3())),
    )
    convert.fill_odometry(msg, snap)
    lin = msg.twist.twist.linear
    assert (lin.x, lin.y, lin.z) == pytest.approx((0.0, -2.0, 0.0), abs=1e-12)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_000)


@pytest.mark.parametrize("t, sec, ns", [(0.0, 0, 0), (0.02, 0, 20_000_000), (100 * 0.01, 1, 0), (123.456789, 123, 456_789_000)])
def test_stamps_are_sim_time_rounded_to_the_nanosecond(t, sec, ns):
    stamp = SimpleNamespace(sec=-1, nanosec=-1)
    convert.fill_stamp(stamp, t)
    assert (stamp.sec, stamp.nanosec) == (sec, ns)


@pytest.mark.parametrize(
    "values, kind",
    [([0.1, 0.2], "wrong_length"), ([math.nan] * 4, "nan"), ([0, 0, -math.inf, 0], "inf"), ([0, 1.01, 0, 0], "out_of_range")],
)
def test_throttle_rejections_are_labelled_by_kind(values, kind):
    assert convert.throttle_fault(values, 4) == kind


def test_default_parameters_are_valid_and_config_file_matches_them():
    for spec in PARAMETERS:
        assert check_parameter(spec.name, spec.default) is None, spec.name
    params = check_params_file(REPO_CONFIG)
    assert {k: params[k] for k in params} == {s.name: s.default for s in PARAMETERS}


@pytest.mark.parametrize(
    "name, value, words",
    [("speed", -1.0, "speed"), ("publish_rate", 0.0, "publish_rate"), ("stabiliser", "maybe", "scene, on, off"),
     ("world_frame", "/mars", "world_frame"), ("seed", -3, "seed"), ("typo_key", 1, "unknown parameter 'typo_key'")],
)
def test_bad_parameters_are_refused_naming_the_key(name, value, words):
    reason = check_parameter(name, value)
    assert reason is not None and words in reason


def test_params_file_with_a_misspelt_key_fails_naming_it(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("lander_sim:\n  ros__parameters:\n    sped: 2.0\n")
    with pytest.raises(ConfigError, match="'sped'"):
        check_params_file(f)


def test_steps_per_tick_makes_the_control_period_a_whole_number_of_steps():
    assert steps_per_tick(0.001, 50.0) == 20
    assert steps_per_tick(0.1, 50.0) == 1  # a step longer than the period: one step per tick


def test_pacer_schedules_ticks_at_the_real_time_factor():
    now = [0.0]
    p = Pacer(speed=10.0, period=0.02, clock=lambda: now[0])
    assert p.wait_time(0.02) == pytest.approx(0.002)  # first tick one period (0.02 s sim / 10) from now
    now[0] = 0.002
    assert p.wait_time(0.04) == pytest.approx(0.002)  # absolute schedule: tick k at k * 0.002 s
    now[0] = 1.0  # far behind (> max_lag = 0.1 s): re-anchor instead of racing
    assert p.wait_time(0.06) == 0.0 and p.overruns == 1
    assert Pacer(speed=0.0, period=0.02, clock=lambda: 0.0).wait_time(5.0) == 0.0


def test_the_pacer_counts_a_loop_that_was_behind_when_it_started_or_stopped():
    """A schedule starts at the restart (a resume), not at the loop's first look at it, and a stop
    (a pause) checks the tick it stops before: a process starved right after a resume or right
    before a pause ran slower than asked, and must say so like a loop late at a tick."""
    now = [0.0]
    p = Pacer(speed=10.0, period=0.02, clock=lambda: now[0])
    p.restart()
    now[0] = 0.05  # first tick due at 0.002; 0.048 late is within max_lag (0.1)
    assert p.wait_time(0.02) == 0.0 and p.overruns == 0
    assert p.wait_time(0.04) == 0.0  # due 0.004: still on the same schedule, behind by 0.046
    now[0] = 0.2
    p.stop(0.06)  # due 0.006, stopped at 0.2: 0.194 behind
    assert p.overruns == 1
    p.restart()  # resumed at 0.2 ...
    now[0] = 0.5  # ... first looked at 0.5: its first tick (due 0.202) is 0.298 late
    assert p.wait_time(0.08) == 0.0 and p.overruns == 2
    assert p.wait_time(0.10) == pytest.approx(0.002)  # re-anchored there
    p.stop(0.12)  # on time: not counted
    p.restart()
    now[0] = 0.9
    p.stop(0.12)  # stopped before its first tick, which was due at 0.502
    assert p.overruns == 3


def test_the_per_tick_readout_agrees_with_the_cores_derived_quantities():
    """The node computes altitude, climb rate, ground speed, mass, Euler angles and the gimbal flag
    itself (cheaper than Simulation.derived()); same definitions, so equal to rounding (1e-9 m/s,
    1e-6 m at 3.4e6 m: a few ulps)."""
    from lander_sim.ros.sim_adapter import build_simulation

    for scene in ("hover", "free-spin", "gimbal-lock-close"):
        sim = build_simulation(scene)
        sim.set_throttles([0.3] * sim.vehicle.n_thrusters)
        for _ in range(5):
            sim.step(7)
            r, d = sim.readout(), sim.sim.derived()
            assert abs(r.altitude - d.altitude) <= 1e-6
            assert abs(r.climb_rate - d.climb_rate) <= 1e-9
            assert abs(r.ground_speed - d.ground_speed) <= 1e-9
            assert r.mass == d.mass and r.gimbal_lock == d.gimbal_lock
            np.testing.assert_array_equal(r.euler, d.euler)


def test_seed_parameter_minus_one_keeps_the_scene_seed_and_a_given_seed_reseeds(tmp_path):
    """The node's default ``seed`` (-1) must fly the scene's own gusts, bit for bit; an explicit
    seed must fly different gusts, and a reset keeps the seed in force."""
    import yaml

    from lander_sim.ros.config import SCENE_SEED
    from lander_sim.ros.sim_adapter import build_simulation
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    assert check_parameter("seed", SCENE_SEED) is None
    scene = yaml.safe_load(load_scene("hover").source.read_text())
    scene.pop("aliases", None)
    scene["name"] = "gusty-hover"
    scene["wind"] = {"mean_W": [0.0, 0.0, 0.0], "gust": {"sigma": 5.0, "tau": 2.0, "seed": 11}}
    path = tmp_path / "gusty-hover.yaml"
    path.write_text(yaml.safe_dump(scene))

    def wind_after(sim, steps=20):
        sim.step(steps)
        return sim.dynamics.inputs.wind_W.copy()

    core = wind_after(Simulation(load_scene(str(path))))
    default = build_simulation(str(path), seed=None)
    np.testing.assert_array_equal(wind_after(default.sim), core)
    other = build_simulation(str(path), seed=12)
    assert not np.array_equal(wind_after(other.sim), core)
    other.reset()
    assert not np.array_equal(wind_after(other.sim), core)  # the given seed stays in force


def test_the_markers_draw_the_vehicles_look_in_the_world_frame():
    """The RViz markers render lander_sim.look (the live scene renders the same): body of size L,
    one arrow per thruster from r_W + R^T p_i along R^T d_i as long as the look's plume (eq 13:
    body -> world), lit ones opaque and unlit ones invisible, in the look's colours; the trail."""
    from lander_sim import look
    from lander_sim.ros.markers import MarkerBuilder
    from lander_sim.ros.sim_adapter import build_simulation

    sim = build_simulation("hover-canted")  # canted thrusters, tilted start: nothing lines up with an axis
    throttles = [0.0, 0.25, 0.5, 1.0]
    sim.set_throttles(throttles)
    builder = MarkerBuilder("mars", trajectory_length=3)
    for _ in range(5):
        sim.step(10)
        snap = sim.readout()
        builder.record(snap.r_W)
    markers = {(m.ns, m.id): m for m in builder.build(snap, sim.vehicle).markers}
    shape = look.Look.of(sim.vehicle)
    colour = lambda m: (m.color.r, m.color.g, m.color.b, m.color.a)  # noqa: E731
    body = markers[("body", 0)]
    assert (body.scale.x, body.scale.y, body.scale.z) == (shape.size,) * 3
    assert colour(body) == pytest.approx(tuple(vars(look.BODY_COLOUR).values()))
    trail = markers[("trajectory", 1)]
    assert len(trail.points) == 3 and trail.points[-1].y == pytest.approx(snap.r_W[1], rel=1e-15)
    assert colour(trail) == pytest.approx(tuple(vars(look.TRAIL_COLOUR).values()))
    for i, plume in enumerate(shape.plumes(throttles)):
        arrow = markers[("plumes", 100 + i)]
        start, end = (np.array([p.x, p.y, p.z]) for p in arrow.points)
        np.testing.assert_allclose(start, snap.r_W + rotation.body_to_world(snap.q, np.array(plume.start_B)),
                                   rtol=0, atol=1e-9)
        np.testing.assert_allclose(end - start, rotation.body_to_world(snap.q, np.subtract(plume.end_B, plume.start_B)),
                                   rtol=0, atol=1e-9)  # |r_W| ~ 3.4e6 m: differences keep ~1e-9 m
        assert plume.length == pytest.approx(look.PLUME_LENGTH_PER_SIZE * shape.size * throttles[i], abs=1e-15)
        rgb = tuple(vars(look.PLUME_COLOUR).values())[:3]
        assert colour(arrow) == pytest.approx((*rgb, 1.0 if throttles[i] > 0 else 0.0))
