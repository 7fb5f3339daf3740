"""The estimator node over real middleware (sim, estimator and autopilot processes, ``lander fly
--estimate --speed 0 --record``), each bag read back with rosbags (not our recorder):

* the node's estimate is the core's: a :class:`TickFeeder` fed the bag's sensor messages (converted
  by the node's own functions) gives every ``/lander/estimate/state`` and ``/lander/estimate/odometry``
  bit for bit;
* the same scene and seed give byte-identical estimate topics over two flights;
* lockstep holds: the bag holds exactly what FLIGHT_ENDED counted, one estimate per state on each
  estimate topic, and the autopilot answered every estimate, sequence for sequence;
* landing-hover-sensors (the landing law from the 500 m hover, every sensor measuring) lands on the
  estimate under 1 m/s; so does landing-sensors (scenario 1 from 10 km, parachute, the radar sensors
  from 4 km down: about a minute and a half of wall time, ``--runslow``).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_autopilot.estimation.ticks import TickFeeder
from lander_autopilot.ros import estimator_convert as convert
from lander_ros.flight_span import SENSOR_KEYS, SENSOR_TOPICS
from lander_sim.scenes import load_scene
from lander_tools.fly.phases import fly
from lander_tools.fly.plan import ESTIMATE_TOPICS, FlightPlan
from lander_tools.fly.summary import summary

from .spancheck import check_span

SCENE = "landing-sensors"
#: Flight length [s] of the two compared flights: the parachute deployed, the radar sensors not
#: yet in range (no reading), the star tracker updating.
DURATION = 6.0
#: The landing flown whole by default: from the hover, the altimeter and Doppler measuring throughout.
LANDING_SCENE = "landing-hover-sensors"


def _fly(bag: Path, duration: float | None, scene: str = SCENE) -> object:
    plan = FlightPlan(scene=scene, duration=duration, speed=0.0, record=bag, estimate=True)
    with open(os.devnull, "w") as devnull:
        result = fly(plan, out=devnull)
    assert result.exit_code == 0, summary(result)
    assert "complete" in result.bag_check and "INCOMPLETE" not in result.bag_check, summary(result)
    assert result.lockstep_timeouts == 0, summary(result)
    return result


def _messages(bag: Path) -> dict[str, list[tuple[bytes, object]]]:
    """Per topic, (raw CDR bytes, decoded message) in the bag's order, read with rosbags."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[bytes, object]]] = {}
    with AnyReader([bag]) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, [])
        for conn, _t, raw in reader.messages():
            out[conn.topic].append((bytes(raw), reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.fixture(scope="module")
def two_flights(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("estimate")
    bags = (tmp / "a", tmp / "b")
    for bag in bags:
        _fly(bag, DURATION)
    return bags


def _core_estimates(got: dict[str, list[tuple[bytes, object]]], scene_name: str) -> list[tuple[object, object, np.ndarray]]:
    """Per state of the bag, the core's (Estimate, NavFilter P, gyro variance) after its tick: a
    TickFeeder fed every sensor message of the bag up to the tick."""
    scene = load_scene(scene_name)
    g = scene.models.get("gravity")
    states = [m for _, m in got["/lander/state"]]
    s0 = states[0]
    assert s0.sequence == 1
    p, v, o = s0.position, s0.velocity, s0.orientation
    feeder = TickFeeder(scene.sensors)
    feeder.start(start_filter(scene.sensors, np.array((p.x, p.y, p.z)), np.array((v.x, v.y, v.z)),
                              np.array((o.w, o.x, o.y, o.z)), convert.stamp_ns(s0.header.stamp) * 1e-9,
                              initial_covariance(scene.sensors), initial_error_rng(scene.sensors.seed),
                              float(g.gm), float(g.radius)))
    for key, topic in zip(SENSOR_KEYS, SENSOR_TOPICS):
        for _, m in got.get(topic, []):
            feeder.add(convert.reading(key, m))
    out = []
    for s in states:
        t = convert.stamp_ns(s.header.stamp)
        assert feeder.ready(t), f"state {s.sequence}: the bag lacks a reading of its tick"
        feeder.advance(t)
        out.append((feeder.estimate(), feeder.filter.state.P.copy(), feeder.omega_var.copy()))
    return out


@pytest.fixture(scope="module")
def landing(tmp_path_factory) -> tuple[object, Path]:
    """landing-hover-sensors flown on the estimate to its touchdown (about 35 s of sim time)."""
    bag = tmp_path_factory.mktemp("landing") / "bag"
    return _fly(bag, None, LANDING_SCENE), bag


def test_the_landing_law_lands_on_the_estimate_under_1_m_s(landing) -> None:
    result, _ = landing
    assert result.outcome == "landed", summary(result)
    assert result.touchdown["descent_rate"] < 1.0, summary(result)


@pytest.mark.slow
def test_scenario_1_from_10_km_lands_on_the_estimate_under_1_m_s_and_the_node_is_the_core(tmp_path: Path) -> None:
    """The whole of landing-sensors: the star tracker from the start, the altimeter and Doppler from
    4 km down (their "no readings" above), the touchdown's last partial step."""
    bag = tmp_path / "bag"
    result = _fly(bag, None)
    assert result.outcome == "landed", summary(result)
    assert result.touchdown["descent_rate"] < 1.0, summary(result)
    _check_node_is_core(bag, SCENE)


def test_the_node_estimate_is_the_core_filter_fed_the_same_messages_bit_for_bit(landing) -> None:
    """Over the whole landing from the hover: every sensor measuring, the touchdown's last partial step."""
    _check_node_is_core(landing[1], LANDING_SCENE, measured=("altimeter", "doppler"))


def test_the_node_estimate_is_the_core_filter_bit_for_bit_where_sensors_give_no_reading(two_flights) -> None:
    """Above the radar sensors' range: their "no reading" messages, the star tracker updating."""
    got = _check_node_is_core(two_flights[0], SCENE)
    assert all(math.isinf(m.range) for _, m in got["/lander/sensors/altimeter"])


def _check_node_is_core(bag: Path, scene: str, measured: tuple[str, ...] = ()) -> dict:
    """Every /lander/estimate/state and /lander/estimate/odometry of ``bag`` equals, bit for bit,
    a TickFeeder fed the bag's sensor messages (converted by the node's own functions); the bag's
    messages, by topic."""
    from nav_msgs.msg import Odometry

    from lander_interfaces.msg import LanderState

    got = _messages(bag)
    states = [m for _, m in got["/lander/state"]]
    est_states = [m for _, m in got["/lander/estimate/state"]]
    est_odom = [m for _, m in got["/lander/estimate/odometry"]]
    assert len(est_states) == len(est_odom) == len(states)
    if "altimeter" in measured:
        assert any(not math.isinf(m.range) for _, m in got["/lander/sensors/altimeter"])
    core = _core_estimates(got, scene)
    gimbal = load_scene(scene).gimbal_threshold

    class _Filt:  # fill_odometry reads the covariance from a filter's state
        def __init__(self, P):
            self.state = type("S", (), {"P": P})

    for truth, node_state, node_odom, (est, P, gyro_var) in zip(states, est_states, est_odom, core):
        want = LanderState()
        convert.fill_state(want, _ros_state(truth), est, gimbal)
        assert node_state.sequence == truth.sequence and node_state.header.stamp == truth.header.stamp
        for field in ("altitude", "climb_rate", "ground_speed", "mass", "fuel_mass"):
            assert getattr(node_state, field) == getattr(want, field), (truth.sequence, field)
        for field in ("position", "velocity", "angular_velocity"):
            a, b = getattr(node_state, field), getattr(want, field)
            assert (a.x, a.y, a.z) == (b.x, b.y, b.z), (truth.sequence, field)
        o, w = node_state.orientation, want.orientation
        assert (o.x, o.y, o.z, o.w) == (w.x, w.y, w.z, w.w), truth.sequence
        assert list(node_state.euler_zxz) == list(want.euler_zxz), truth.sequence
        odom = Odometry()
        convert.fill_odometry(odom, _ros_state(truth), est, _Filt(P), gyro_var)
        assert list(node_odom.pose.covariance) == list(odom.pose.covariance), truth.sequence
        assert list(node_odom.twist.covariance) == list(odom.twist.covariance), truth.sequence
        tl, wl = node_odom.twist.twist.linear, odom.twist.twist.linear
        assert (tl.x, tl.y, tl.z) == (wl.x, wl.y, wl.z), truth.sequence
    # and it is an estimate, not the truth: it differs by the drawn initial error
    last, truth = est_states[-1], states[-1]
    err = math.dist((last.position.x, last.position.y, last.position.z),
                    (truth.position.x, truth.position.y, truth.position.z))
    assert 0.0 < err < 100.0
    return got


def _ros_state(m):
    """A rosbags-decoded LanderState as the rclpy message fill_state copies fields from."""
    from lander_interfaces.msg import LanderState

    s = LanderState()
    s.header.stamp.sec, s.header.stamp.nanosec = m.header.stamp.sec, m.header.stamp.nanosec
    s.header.frame_id = m.header.frame_id
    s.sequence = m.sequence
    s.mass, s.fuel_mass = m.mass, m.fuel_mass
    s.throttles = [float(x) for x in m.throttles]
    s.phase, s.parachute_deployed, s.stabiliser_on = m.phase, m.parachute_deployed, m.stabiliser_on
    return s


def test_the_same_scene_and_seed_give_byte_identical_estimate_topics(two_flights) -> None:
    a, b = (_messages(bag) for bag in two_flights)
    for topic in ESTIMATE_TOPICS:
        ra, rb = [m[0] for m in a[topic]], [m[0] for m in b[topic]]
        assert ra, f"{topic}: no message"
        assert ra == rb, f"{topic}: the two flights differ"


def test_lockstep_on_the_estimate_one_estimate_and_one_answer_per_state(two_flights) -> None:
    bag = two_flights[0]
    span = check_span(bag, DURATION, lockstep=True, sim_only_events=False)  # FLIGHT_ENDED's counts, exactly
    got = _messages(bag)
    n = span.end.counts["/lander/state"]
    for topic in ESTIMATE_TOPICS:
        assert len(got[topic]) == n, f"{topic}: {len(got[topic])} messages for {n} states"
    seqs = [m.sequence for _, m in got["/lander/estimate/state"]]
    assert seqs == list(range(1, n + 1))
    assert sorted(m.state_sequence for _, m in got["/lander/throttle"]) == seqs
    # every due sample is a message, a "no reading" included: floor(D f) + 1 per sensor
    rates = {k: float(v["rate"]) for k, v in load_scene(SCENE).sensors.sections.items()}
    for key, rate in rates.items():
        assert span.end.counts[f"/lander/sensors/{key}"] == math.floor(DURATION * rate + 1e-9) + 1, key

