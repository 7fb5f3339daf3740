"""The live bridge's plain parts (no ROS, no server): frames and plumes of the 3-D scene (the
vehicle's look, the same the sim's RViz markers draw), the client input checks, the page server,
the shipped Foxglove layout."""
from __future__ import annotations

import json
import re
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from lander_sim.look import PLUME_LENGTH_PER_SIZE, Look
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.rotation import body_to_world
from lander_sim.scenes import load_scene
from lander_tools.live import views
from lander_tools.live.clientinput import (
    SERVICE_FIELDS,
    ClientInputError,
    parse_client_message,
    parse_service_request,
)

REPO = Path(__file__).resolve().parents[2]


def rotate(q_xyzw: tuple[float, float, float, float], v: np.ndarray) -> np.ndarray:
    """Active rotation of v by the ROS quaternion (x, y, z, w): what a viewer does with a pose."""
    x, y, z, w = q_xyzw
    return body_to_world(np.array([w, x, y, z]), v)


def test_surface_frame_sits_on_the_ground_below_the_first_position_with_z_up() -> None:
    r_W = np.array([1200.0, -MARS_RADIUS - 550.0, 300.0])
    tr = views.SceneTracker(Look(1.0))
    here = tr.add(r_W)
    pose = tr.surface_pose()
    up = r_W / np.linalg.norm(r_W)
    np.testing.assert_allclose(pose.position, MARS_RADIUS * up, rtol=0, atol=1e-6)
    # The pose maps surface axes into mars: z is the local vertical; the point is 550 m above.
    np.testing.assert_allclose(rotate(pose.orientation, np.array([0.0, 0.0, 1.0])), up, atol=1e-12)
    np.testing.assert_allclose(here, (0.0, 0.0, np.linalg.norm(r_W) - MARS_RADIUS), atol=1e-6)
    # And back: surface point -> mars through the pose gives the world position.
    back = np.asarray(pose.position) + rotate(pose.orientation, np.asarray(here))
    np.testing.assert_allclose(back, r_W, rtol=0, atol=1e-6)


def test_body_up_is_the_body_z_axis_in_the_surface_frame() -> None:
    scene = load_scene("hover-canted")  # tilted start: a non-trivial attitude
    q = scene.initial_state[6:10] / np.linalg.norm(scene.initial_state[6:10])
    tr = views.SceneTracker(Look(1.0))
    tr.add(scene.initial_state[0:3])
    up_S = np.array(tr.body_up((q[1], q[2], q[3], q[0])))
    z_W = body_to_world(q, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(tr.R_WS @ up_S, z_W, atol=1e-12)
    assert np.linalg.norm(up_S) == pytest.approx(1.0, abs=1e-12)


def test_plumes_scale_with_throttle_along_the_exhaust() -> None:
    v = load_scene("hover-canted").vehicle
    throttles = [0.0, 0.25, 0.5, 1.0]
    for thr, u, plume in zip(v.thrusters, throttles, Look.of(v).plumes(throttles)):
        np.testing.assert_allclose(plume.start_B, thr.position_B)
        np.testing.assert_allclose(np.subtract(plume.end_B, plume.start_B),
                                   PLUME_LENGTH_PER_SIZE * v.size * u * np.asarray(thr.direction_B), atol=1e-12)
        pose, length = views.plume_pose(plume)
        assert length == pytest.approx(PLUME_LENGTH_PER_SIZE * v.size * u, abs=1e-12)
        if length > 0:  # the cylinder's axis (local z) lies along the exhaust, centred on the plume
            axis = rotate(pose.orientation, np.array([0.0, 0.0, 1.0]))
            np.testing.assert_allclose(axis, np.asarray(thr.direction_B) / np.linalg.norm(thr.direction_B), atol=1e-12)
            np.testing.assert_allclose(pose.position, (np.asarray(plume.start_B) + plume.end_B) / 2, atol=1e-12)


def test_view_fields_give_the_body_in_the_surface_frame_its_tilt_and_its_lit_plumes() -> None:
    """The 3-D view's orientation q_SB, read actively, carries the body axes into the surface frame:
    its z axis is body_up (computed through body_to_world, another path); the tilt is the angle of
    that axis from the local vertical, which at the anchor is the surface z axis."""
    scene = load_scene("hover-canted")
    q = scene.initial_state[6:10] / np.linalg.norm(scene.initial_state[6:10])
    r_W = scene.initial_state[0:3]
    tr = views.SceneTracker(Look.of(scene.vehicle))
    tr.add(r_W)
    q_xyzw = (q[1], q[2], q[3], q[0])
    f = views.view_fields(tr, r_W, q_xyzw, [0.0, 0.5, 1.0, 0.0], parachute=True)
    up_S = np.array(tr.body_up(q_xyzw))
    np.testing.assert_allclose(rotate(tuple(f["q_SB"]), np.array([0.0, 0.0, 1.0])), up_S, atol=1e-12)
    for axis in np.eye(3):  # every body axis, not only z
        np.testing.assert_allclose(tr.R_WS @ rotate(tuple(f["q_SB"]), axis), body_to_world(q, axis), atol=1e-12)
    assert f["tilt"] == pytest.approx(np.arccos(up_S[2]), abs=1e-9)
    assert f["q_WB"] == pytest.approx(list(q_xyzw))
    # Two lit plumes, each 2 L x throttle long; the canopy at its place in the look.
    lengths = sorted(float(np.linalg.norm(np.subtract(p[3:], p[:3]))) for p in f["plumes_B"])
    assert lengths == pytest.approx([PLUME_LENGTH_PER_SIZE * scene.vehicle.size * u for u in (0.5, 1.0)])
    look = Look.of(scene.vehicle)
    assert f["parachute_B"] == pytest.approx([*look.parachute_centre_B(), *look.parachute_extent()])
    assert views.view_fields(tr, r_W, q_xyzw, [0.0] * 4, parachute=False)["parachute_B"] is None
    # A body turned by a about the surface x axis at the anchor is tilted by a.
    for a in (0.0, 0.3, 1.2, 3.0):
        R_SB = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        from lander_sim.physics.rotation import matrix_to_quat

        qc = matrix_to_quat((tr.R_WS @ R_SB).T)  # the core's q maps world to body: R(q) = R_WB^T
        g = views.view_fields(tr, r_W, (qc[1], qc[2], qc[3], qc[0]), [0.0] * 4, parachute=False)
        assert g["tilt"] == pytest.approx(a, abs=1e-9)


def test_history_keeps_the_epoch_from_t0_within_its_capacity_and_restarts_on_a_reset() -> None:
    h = views.History(capacity=100)
    dt = 0.02
    for k in range(5000):  # 100 s of states at 50 Hz
        h.add({"t": k * dt, "altitude": 500.0 + k, "climb_rate": 0.0})
    t = [r["t"] for r in h.records]
    assert t[0] == 0.0 and len(t) <= 100 and t[-1] >= 100.0 - 2 * h.spacing
    gaps = np.diff(t)  # even spacing: the whole flight at one resolution, to within one state interval
    assert h.spacing - dt - 1e-9 <= gaps.min() and gaps.max() <= h.spacing + dt + 1e-9
    assert set(h.records[0]) == set(views.HISTORY_FIELDS)
    h.add({"t": 0.0, "altitude": 550.0})  # sim time going back: a reset, a new epoch
    assert [r["t"] for r in h.records] == [0.0] and h.spacing == 0.0


def test_trail_is_bounded_and_reset_starts_a_new_one() -> None:
    tr = views.SceneTracker(Look(1.0), trail_length=5)
    for k in range(8):
        tr.add([0.0, -MARS_RADIUS - 100.0 - k, 0.0])
    assert len(tr.trail_S) == 5 and tr.trail_S[-1][2] == pytest.approx(107.0)
    tr.reset()
    assert len(tr.trail_S) == 0 and tr.origin_W is None


@pytest.mark.parametrize(("topic", "payload", "expected"), [
    ("/lander/demand_altitude", b'{"data": 510}', ("demand", 510.0)),
    ("/lander/wind", b'{"x": 1, "y": -2.5, "z": 0}', ("wind", [1.0, -2.5, 0.0])),
    ("/lander/wind", b'{"x": NaN, "y": 0, "z": 0}', None),  # forwarded: the sim judges NaN
    ("/lander/throttle", b'{"throttles": [0, 0.5, 1, 1]}', ("throttle", [0.0, 0.5, 1.0, 1.0])),
])
def test_client_messages_are_decoded_for_forwarding(topic: str, payload: bytes, expected: object) -> None:
    kind, value = parse_client_message(topic, payload)
    if expected is None:
        assert kind == "wind" and np.isnan(value[0])
    else:
        assert (kind, value) == expected


@pytest.mark.parametrize(("topic", "payload", "message"), [
    ("/lander/wind", b"{x: 1}", "/lander/wind: not JSON"),
    ("/lander/wind", b'{"x": "east", "y": 0, "z": 0}', "field 'x' must be a number, got 'east'"),
    ("/lander/wind", b'[1, 2, 3]', "field 'x' must be a number"),
    ("/lander/demand_altitude", b'{"data": true}', "field 'data' must be a number, got True"),
    ("/lander/throttle", b'{"throttles": 0.5}', "field 'throttles' must be a list of numbers"),
    ("/lander/state", b'{}', "/lander/state: not a topic clients may publish"),
])
def test_client_messages_that_cannot_be_forwarded_say_why(topic: str, payload: bytes, message: str) -> None:
    with pytest.raises(ClientInputError, match=re.escape(message)):
        parse_client_message(topic, payload)


def test_service_requests_are_checked_against_the_ros_fields() -> None:
    assert parse_service_request("/lander/step", b'{"steps": 7}') == {"steps": 7}
    assert parse_service_request("/lander/pause", b"") == {}
    for payload, message in ((b'{"steps": -1}', "field 'steps' must be a non-negative integer, got -1"),
                             (b'{"steps": 1.5}', "must be a non-negative integer"),
                             (b'{"stepz": 1}', "unknown field 'stepz' (fields: steps)"),
                             (b'[]', "request must be a JSON object")):
        with pytest.raises(ClientInputError, match=re.escape(message)):
            parse_service_request("/lander/step", payload)


def test_page_server_serves_only_the_page_files_and_the_ws_port() -> None:
    from lander_tools.live.page import WEB_DIR, PageServer

    page = PageServer("127.0.0.1", 0, ws_port=12345)
    try:
        base = f"http://127.0.0.1:{page.port}"
        assert json.loads(urllib.request.urlopen(f"{base}/config.json").read()) == {"mode": "live", "ws_port": 12345}
        assert urllib.request.urlopen(f"{base}/").read() == (WEB_DIR / "index.html").read_bytes()
        assert b"foxglove.sdk.v1" in urllib.request.urlopen(f"{base}/foxglove.js").read()
        for bad in ("/../bridge.py", "/%2e%2e/bridge.py", "/nope.js"):
            with pytest.raises(urllib.error.HTTPError) as err:
                urllib.request.urlopen(base + bad)
            assert err.value.code == 404
    finally:
        page.close()
    # Nothing is fetched from the internet: the page names no remote URL.
    for f in WEB_DIR.iterdir():
        assert not re.search(r"(src|href)=[\"']?(https?:)?//", f.read_text()), f.name


def test_shipped_foxglove_layout_uses_only_what_the_bridge_serves() -> None:
    layout = json.loads((REPO / "config" / "foxglove-live-layout.json").read_text())
    panels = layout["configById"]
    used = set(re.findall(r'"([A-Za-z0-9]+![a-z]+)"', json.dumps(layout["layout"])))
    assert used == set(panels)
    served = {"/live/state", "/live/events", "/live/status", "/live/scene", "/live/tf"}
    for pid, cfg in panels.items():
        if pid.startswith("Plot!"):
            for path in cfg["paths"]:
                topic, field = path["value"].split(".")
                assert topic == "/live/state" and field.split("[")[0] in views.STATE_SCHEMA["properties"], path
        if pid.startswith("CallService!"):
            assert cfg["serviceName"] in SERVICE_FIELDS, pid
            parse_service_request(cfg["serviceName"], cfg["requestPayload"].encode())
        if pid.startswith("Publish!"):
            parse_client_message(cfg["topicName"], cfg["value"].encode())
        if pid.startswith("RawMessages!"):
            assert cfg["topicPath"] in served
    assert panels["3D!lander"]["followTf"] == "base_link"


@pytest.mark.parametrize("name", ["live", "view", "demand", "wind", "switch", "pause", "resume", "step", "reset", "topics",
                                  "echo"])
def test_each_new_command_explains_itself(capsys: pytest.CaptureFixture[str], name: str) -> None:
    from lander_tools import cli

    with pytest.raises(SystemExit) as exc:
        cli.main([name, "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and out.startswith(f"usage: lander {name}")
    if name not in ("live", "view"):
        assert "--wait S" in out


def test_bad_verb_arguments_are_one_line_before_any_ros(capsys: pytest.CaptureFixture[str]) -> None:
    from lander_tools import cli

    assert cli.main(["step", "-1"]) == 2
    assert capsys.readouterr().err.strip() == "lander step: N must be an integer in 0..4294967295, got -1"
    assert cli.main(["echo", "lander/state"]) == 2
    assert "topic names are absolute" in capsys.readouterr().err
