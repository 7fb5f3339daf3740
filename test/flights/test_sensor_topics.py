"""The simulator publishes a scene's sensors (docs/sim_node.md, "Sensors"): real flights over ROS
(sim and autopilot processes, ``lander fly --speed 0 --record``), each bag read back with rosbags
(not our recorder) and with the independent mcap reader (spancheck.py).

* every sensor's topic holds one message per instant ``j / f`` of ``[0, D]`` (``floor(D f) + 1``),
  stamped at exactly those sim times, in its standard type;
* the bag holds exactly what FLIGHT_ENDED counted, the sensor topics included;
* the same scene and seed give byte-identical sensor messages;
* a scene without sensors publishes none (its FLIGHT_ENDED carries no sensor counts).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
import yaml

from lander_ros.flight_span import SENSOR_TOPICS
from lander_sim.scenes import load_scene
from lander_tools.fly.phases import fly
from lander_tools.fly.plan import FlightPlan
from lander_tools.fly.summary import summary
from lander_tools.recorder import DEFAULT_TOPICS

from .spancheck import STAMP_EPS, check_span

#: Flight length [s]: 100 control periods of 0.02 s; every sensor's period divides it.
DURATION = 2.0
#: Rate [Hz] of each sensor in the test scene (the packaged landing-sensors, its ground fix at 1 Hz).
RATES = {"imu": 100.0, "star_tracker": 5.0, "altimeter": 20.0, "doppler": 20.0, "ground_fix": 1.0}
TYPES = {"imu": "sensor_msgs/msg/Imu", "star_tracker": "geometry_msgs/msg/PoseWithCovarianceStamped",
         "altimeter": "sensor_msgs/msg/Range", "doppler": "geometry_msgs/msg/TwistWithCovarianceStamped",
         "ground_fix": "nav_msgs/msg/Odometry"}


def _scene(tmp_path: Path) -> Path:
    """landing-sensors from a 500 m hover (inside the altimeter's and Doppler's 4 km), with a ground fix
    at 1 Hz: no sensor drops out in the first seconds (the lander upright, at rest)."""
    src = yaml.safe_load(Path(load_scene("landing-sensors").source).read_text())
    src["name"] = "landing-sensors-500m"
    src["initial"]["position_W"] = [0.0, -3386500.0, 0.0]  # R + 500 m
    src["sensors"]["ground_fix"] = {"rate": RATES["ground_fix"]}
    path = tmp_path / "landing-sensors-500m.yaml"
    path.write_text(yaml.safe_dump(src))
    return path


def _fly(scene: str, bag: Path, topics: tuple[str, ...] | None = None, **sim_params: object):
    plan = FlightPlan(scene=scene, duration=DURATION, speed=0.0, record=bag, topics=topics, sim_params=sim_params)
    with open(os.devnull, "w") as devnull:
        result = fly(plan, out=devnull)
    assert result.exit_code == 0 and result.outcome == "time-limit", summary(result)
    assert "complete" in result.bag_check and "INCOMPLETE" not in result.bag_check, summary(result)
    return result


def _raw(bag: Path) -> dict[str, list[tuple[str, bytes, object]]]:
    """Per topic, (type, raw CDR bytes, decoded message) in the bag's order, read with rosbags."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[str, bytes, object]]] = {}
    with AnyReader([bag]) as reader:
        for conn in reader.connections:
            out.setdefault(conn.topic, [])
        for conn, _t, raw in reader.messages():
            out[conn.topic].append((conn.msgtype, bytes(raw), reader.deserialize(raw, conn.msgtype)))
    return out


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


@pytest.fixture(scope="module")
def two_flights(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("sensors")
    scene = str(_scene(tmp))
    bags = (tmp / "a", tmp / "b")
    for bag in bags:
        _fly(scene, bag)
    return bags


def test_each_sensor_topic_holds_one_message_per_instant_of_its_rate_stamped_in_sim_time(two_flights) -> None:
    bag = two_flights[0]
    span = check_span(bag, DURATION, lockstep=True, sim_only_events=False)  # the FLIGHT_ENDED counts, exactly
    got = _raw(bag)
    for key, rate in RATES.items():
        topic = f"/lander/sensors/{key}"
        n = math.floor(DURATION * rate + 1e-9) + 1
        assert span.end.counts[topic] == n, f"{topic}: the sim counted {span.end.counts[topic]}, expected {n}"
        msgs = got.get(topic, [])
        assert len(msgs) == n, f"{topic}: {len(msgs)} messages in the bag, expected {n} (= {DURATION} s x {rate} Hz + 1)"
        assert {m[0] for m in msgs} == {TYPES[key]}
        stamps = [_stamp(m[2]) for m in msgs]
        # one ROS stamp is integer nanoseconds: the sim time j/f to within its rounding
        off = max(abs(t - j / rate) for j, t in enumerate(stamps))
        assert off <= STAMP_EPS, f"{topic}: a stamp {off} s off the sim time j/f"


def test_the_messages_carry_the_measurement_and_its_noise_in_the_standard_fields(two_flights) -> None:
    """Each measurement against the truth the sim published at the same instant (/lander/state), within
    six standard deviations of its noise (and bias): the fields hold the quantity they name."""
    got = _raw(two_flights[0])
    states = {round(_stamp(m[2]), 6): m[2] for m in got["/lander/state"]}
    # the law coasts from rest: thrusters off, so the lander falls freely
    assert all(not any(s.throttles) for s in states.values())
    b0 = 300e-6 * 9.80665  # the IMU's accelerometer switch-on bias, 1 sigma (its default)
    for _, _, imu in got["/lander/sensors/imu"]:
        # free fall: the accelerometer reads the specific force, about 0 (drag only), not gravity's 3.7 m/s^2
        f = (imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z)
        tol = 6.0 * (math.sqrt(imu.linear_acceleration_covariance[0]) + b0)
        assert max(abs(x) for x in f) < tol, (f, tol)
        assert imu.orientation_covariance[0] == -1.0  # no orientation: sensor_msgs' "not provided"
        assert imu.header.frame_id == "base_link"
    checked = 0
    for _, _, alt in got["/lander/sensors/altimeter"]:
        s = states.get(round(_stamp(alt), 6))
        if s is not None:  # upright over flat ground: the slant range down the body is the altitude
            assert abs(alt.range - s.altitude) < 6.0 * math.sqrt(alt.variance), (alt.range, s.altitude)
            checked += 1
        assert alt.max_range == 4000.0
    for _, _, st in got["/lander/sensors/star_tracker"]:
        s = states.get(round(_stamp(st), 6))
        q, o = st.pose.pose.orientation, s.orientation
        angle = 2.0 * math.acos(min(1.0, abs(q.x * o.x + q.y * o.y + q.z * o.z + q.w * o.w)))
        assert angle < 6.0 * math.sqrt(3.0 * st.pose.covariance[21]), angle
        assert st.pose.covariance[0] == -1.0 and st.header.frame_id == "mars"  # position not measured
        checked += 1
    for _, _, fix in got["/lander/sensors/ground_fix"]:
        s = states[round(_stamp(fix), 6)]
        assert fix.header.frame_id == fix.child_frame_id == "mars"  # position and velocity in world axes
        err = math.dist((fix.pose.pose.position.x, fix.pose.pose.position.y, fix.pose.pose.position.z),
                        (s.position.x, s.position.y, s.position.z))
        assert err < 6.0 * math.sqrt(3.0 * fix.pose.covariance[0]), err
        checked += 1
    assert checked > 20


def test_the_same_scene_and_seed_give_byte_identical_sensor_topics(two_flights) -> None:
    a, b = (_raw(bag) for bag in two_flights)
    for topic in SENSOR_TOPICS:
        ra, rb = [m[1] for m in a[topic]], [m[1] for m in b[topic]]
        assert ra, f"{topic}: no message"
        assert ra == rb, f"{topic}: the two flights differ from message {next(i for i, (x, y) in enumerate(zip(ra, rb)) if x != y)}"


def test_the_sim_seed_draws_other_noise_over_the_same_flight(two_flights, tmp_path: Path) -> None:
    """The node's ``seed`` re-seeds the sensors: other measurements, while the flight (on the truth,
    no gusts in this scene) is the same bits."""
    bag = tmp_path / "seed5"
    _fly(str(two_flights[0].parent / "landing-sensors-500m.yaml"), bag, seed=5)
    a, b = _raw(two_flights[0]), _raw(bag)
    assert [m[1] for m in a["/lander/state"]] == [m[1] for m in b["/lander/state"]]
    for topic in SENSOR_TOPICS:
        assert len(a[topic]) == len(b[topic]) and all(x[1] != y[1] for x, y in zip(a[topic], b[topic])), topic


def test_a_scene_without_sensors_publishes_none(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    _fly("landing-hover", bag, topics=DEFAULT_TOPICS)  # the recorder asks for the sensor topics too
    got = _raw(bag)
    assert not [t for t in got if t.startswith("/lander/sensors/")], sorted(got)
    span = check_span(bag, DURATION, lockstep=True, sim_only_events=False)
    assert not span.end.has_sensors and not any(t in span.end.counts for t in SENSOR_TOPICS)


def test_record_whole_flight_records_the_sensor_topics_the_sim_publishes(tmp_path: Path) -> None:
    """`lander record --whole-flight` beside a sim started as `ros2 run` starts it: the sensors the
    sim publishes are waited for, recorded from t = 0 and checked against FLIGHT_ENDED like its other
    outputs. From 10 km only the IMU and the star tracker are in range (altimeter and Doppler: 4 km): the
    radar sensors' due samples are all "no readings" (the altimeter's range +inf, REP 117; variances -1)."""
    import rosutil

    from .flightcheck import REPO, lander

    bag = tmp_path / "whole"
    args = ["-m", "lander_sim.node", "--ros-args", "-p", "scene:=landing-sensors", "-p", "speed:=0.0",
            "-p", "command_timeout:=0.0"]
    with rosutil.ChildProcess(args, cwd=REPO, name="lander_sim") as sim:
        r = lander("record", "-o", str(bag), "--whole-flight", "--duration", str(DURATION), "--wait", "30", timeout=90.0)
        assert r.returncode == 0, r.stdout + r.stderr + sim.output()
    assert f"complete: the whole flight, t = 0 to {DURATION} s (time-limit)" in r.stdout, r.stdout
    span = check_span(bag, DURATION)
    for key in ("imu", "star_tracker", "altimeter", "doppler"):
        topic = f"/lander/sensors/{key}"
        assert span.counts[topic] == span.end.counts[topic] == math.floor(DURATION * RATES[key] + 1e-9) + 1, topic
    got = _raw(bag)
    assert all(math.isinf(m[2].range) and m[2].variance == -1.0 for m in got["/lander/sensors/altimeter"])
    assert all(m[2].twist.covariance[0] == -1.0 for m in got["/lander/sensors/doppler"])
