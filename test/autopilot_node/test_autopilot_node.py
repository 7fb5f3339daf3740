"""The autopilot node alone, over the real middleware: the test publishes the states.

The node runs as a process with config/autopilot.yaml; the test plays the simulator, one state at
a time (waiting for each answer, as a lockstep simulator does), and checks every answer against
the same controller evaluated here on the same message, converted by the same function: the
throttles must be *equal*, bit for bit (same code, same inputs, same IEEE arithmetic).
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from lander_autopilot.controllers import UPRIGHT_EULER, Demand, make_controller
from lander_autopilot.ros.config import parse_controller_params
from lander_autopilot.ros.convert import state_view
from lander_interfaces.msg import FlightEvent, LanderState
from lander_sim.physics import rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.ros.convert import fill_state
from lander_sim.scenes import load_scene
from rosutil import REPO

from .ground import START_TIMEOUT

PARAMS_FILE = REPO / "config" / "autopilot.yaml"
FILE_PARAMS = yaml.safe_load(PARAMS_FILE.read_text())["autopilot"]["ros__parameters"]
STATE_TIMEOUT = 0.5  # s wall: short, so that the loss test is quick


@pytest.fixture(scope="module")
def autopilot(rig):
    rig.start("lander_autopilot.node", "autopilot", {"state_timeout": STATE_TIMEOUT}, params_file=str(PARAMS_FILE))
    g = rig.ground
    g.wait_for(lambda: g.node.count_subscribers("/lander/state") >= 1 and g.node.count_publishers("/lander/throttle") >= 1,
               START_TIMEOUT, "the autopilot's state subscription and throttle publisher")
    g.wait_for(g.switch.service_is_ready, START_TIMEOUT, "the switch service")
    rig.seq = 0
    return rig


def file_controller():
    """The controller config/autopilot.yaml asks for, built here."""
    vehicle = load_scene(FILE_PARAMS["scene"]).vehicle
    return make_controller(FILE_PARAMS["controller"], vehicle, **parse_controller_params(FILE_PARAMS["controller_params"]))


def make_state(seq: int, t: float, rng: np.random.Generator, n_thrusters: int = 4) -> LanderState:
    """A perturbed hover state on the -y axis, written by the simulator's own message writer."""
    E = np.array(UPRIGHT_EULER) + rng.normal(0.0, 0.05, 3)
    q = rotation.euler_to_quat(E)
    h = 500.0 + rng.normal(0.0, 5.0)
    snap = SimpleNamespace(
        t=t, r_W=np.array((0.0, -(MARS_RADIUS + h), 0.0)) + rng.normal(0.0, 1.0, 3) * (1, 0, 1),
        v_W=rng.normal(0.0, 0.5, 3), q=q, euler=rotation.quat_to_euler(q), gimbal_lock=False,
        omega_B=rng.normal(0.0, 0.02, 3), altitude=h, climb_rate=0.0, ground_speed=0.0, mass=180.0, fuel=80.0,
        throttles=np.full(n_thrusters, 0.4), phase=0, parachute_deployed=False, stabiliser_on=False,
    )
    msg = LanderState()
    fill_state(msg, seq, snap)
    return msg


def ask(rig, msg: LanderState, timeout: float = 10.0):
    """Publish one state and wait for the autopilot's answer to it."""
    g = rig.ground
    mark = len(g.throttles)
    g.pub_state.publish(msg)
    g.wait_for(lambda: g.answer_to(msg.sequence, mark) is not None, timeout, f"answer to state {msg.sequence}")
    return g.answer_to(msg.sequence, mark)


def fly_states(rig, n: int, rng: np.random.Generator) -> list[tuple[LanderState, list[float]]]:
    out = []
    for _ in range(n):
        rig.seq += 1
        msg = make_state(rig.seq, 0.1 * rig.seq, rng)
        out.append((msg, list(ask(rig, msg).throttles)))
    return out


def expected(controller, msg: LanderState, demand_altitude: float = 500.0) -> list[float]:
    state = state_view(msg)
    return controller.update(state.t, state, Demand(altitude=demand_altitude)).throttles.tolist()


def latest_status(rig):
    rig.ground.drain()
    return rig.ground.statuses[-1]


def test_every_state_is_answered_with_the_controller_evaluated_on_that_state(autopilot):
    rng = np.random.default_rng(1)
    law = file_controller()
    pairs = fly_states(autopilot, 20, rng)
    for msg, u in pairs:
        assert u == expected(law, msg), f"state {msg.sequence}"
    last = autopilot.ground.answer_to(pairs[-1][0].sequence)
    assert last.header.stamp == pairs[-1][0].header.stamp  # stamp copied: latency measurable
    status = latest_status(autopilot)
    assert status.controller == "combined" and status.throttles.tolist() == pairs[-1][1]


def test_the_switch_service_swaps_between_two_states_and_is_recorded(autopilot):
    g = autopilot.ground
    rng = np.random.default_rng(2)
    vehicle = load_scene(FILE_PARAMS["scene"]).vehicle
    old = file_controller()
    new = make_controller("combined-quaternion", vehicle, altitude_poles=[-1.0, -1.2])
    before = fly_states(autopilot, 5, rng)
    events0 = len(g.events)
    reply = g.switch_controller("combined-quaternion", "{altitude_poles: [-1.0, -1.2]}")
    assert reply.success and reply.active_controller == "combined-quaternion", reply.message
    after = fly_states(autopilot, 5, rng)
    assert all(u == expected(old, m) for m, u in before)
    assert all(u == expected(new, m) for m, u in after)
    assert any(expected(old, m) != expected(new, m) for m, _ in after)  # the laws do differ
    g.drain()
    ev = [e for e in g.events[events0:] if e.kind == FlightEvent.CONTROLLER_SWITCHED]
    assert len(ev) == 1 and ev[0].values.tolist() == [float(before[-1][0].sequence)]
    assert "'combined' -> 'combined-quaternion'" in ev[0].detail
    assert g.autopilot_parameter("controller") == "combined-quaternion"
    # Back to the file's controller through the parameters (atomic pair) this time.
    result = g.set_autopilot_parameters(controller="combined", controller_params=FILE_PARAMS["controller_params"])
    assert result.successful, result.reason
    assert all(u == expected(old, m) for m, u in fly_states(autopilot, 3, rng))


@pytest.mark.parametrize("bad, words", [(math.nan, "finite"), (-3.0, "below the ground"), (math.inf, "finite")])
def test_a_bad_demand_is_refused_counted_announced_and_the_previous_one_kept(autopilot, bad, words):
    g = autopilot.ground
    rng = np.random.default_rng(3)
    law = file_controller()
    good = 520.0
    g.publish_demand(good)
    g.wait_for(lambda: g.autopilot_parameter("demand_altitude") == good, what="demand 520 m in force")
    rejected0 = latest_status(autopilot).rejected
    events0 = len(g.events)
    g.publish_demand(bad)
    g.wait_for(lambda: any(e.kind == FlightEvent.INPUT_REJECTED for e in g.events[events0:]), what="rejection event")
    ev = next(e for e in g.events[events0:] if e.kind == FlightEvent.INPUT_REJECTED)
    assert "demand_altitude" in ev.detail and words in ev.detail
    assert all(u == expected(law, m, good) for m, u in fly_states(autopilot, 3, rng))
    status = latest_status(autopilot)
    assert status.rejected == rejected0 + 1 and words in status.last_error
    g.publish_demand(500.0)
    g.wait_for(lambda: g.autopilot_parameter("demand_altitude") == 500.0, what="demand back to 500 m")


@pytest.mark.parametrize("controller, params, words", [
    ("no-such-law", "", ["unknown controller 'no-such-law'", "available:", "combined"]),
    ("attitude-euler", "{K: [[1.0, 2.0], [3.0, 4.0]]}", ["K", "(4, 6)", "(2, 2)"]),
    ("altitude", "{poles: [-1.0]}", ["poles", "expected 2 poles"]),
    ("altitude", "{gain: 3}", ["unknown parameter", "gain"]),
    ("altitude", "[1, 2", ["controller_params", "YAML"]),
])
def test_an_unknown_controller_or_ill_shaped_gains_are_refused_and_the_running_controller_flies_on(
        autopilot, controller, params, words):
    g = autopilot.ground
    rng = np.random.default_rng(4)
    law = file_controller()
    reply = g.switch_controller(controller, params)
    assert not reply.success and reply.active_controller == "combined"
    for w in words:
        assert w in reply.message, reply.message
    result = g.set_autopilot_parameters(controller=controller, controller_params=params)  # the other door
    assert not result.successful and all(w in result.reason for w in words), result.reason
    assert all(u == expected(law, m) for m, u in fly_states(autopilot, 3, rng))
    assert g.autopilot_parameter("controller") == "combined"


def test_a_state_that_cannot_be_flown_gets_no_command_and_is_counted(autopilot):
    g = autopilot.ground
    rng = np.random.default_rng(5)
    rejected0 = latest_status(autopilot).rejected
    autopilot.seq += 1
    bad = make_state(autopilot.seq, 0.1 * autopilot.seq, rng)
    bad.velocity.x = math.nan
    autopilot.seq += 1
    other_vehicle = make_state(autopilot.seq, 0.1 * autopilot.seq, rng, n_thrusters=1)
    mark = len(g.throttles)
    for msg, words in ((bad, "velocity is not finite"), (other_vehicle, "reports 1 thrusters")):
        g.pub_state.publish(msg)
        g.wait_for(lambda: latest_status(autopilot).rejected == rejected0 + 1, what=f"state {msg.sequence} refused")
        rejected0 += 1
        assert words in g.statuses[-1].last_error, g.statuses[-1].last_error
        assert g.answer_to(msg.sequence, mark) is None, "a command answered a state that cannot be flown"
    assert "scene" in g.statuses[-1].last_error  # says what to do
    fly_states(autopilot, 2, rng)  # and it flies on


def test_losing_the_state_stream_is_reported_and_nothing_is_commanded(autopilot):
    g = autopilot.ground
    rng = np.random.default_rng(6)
    fly_states(autopilot, 2, rng)
    assert latest_status(autopilot).state_ok  # the status sent with the last answer
    mark = len(g.throttles)
    g.wait_for(lambda: "state lost" in g.statuses[-1].last_error, 10 * STATE_TIMEOUT + 5.0, "loss reported")
    assert not g.statuses[-1].state_ok
    g.drain()
    assert len(g.throttles) == mark, "a command was sent without a state"
    fly_states(autopilot, 1, rng)  # back to normal when states come again
    assert latest_status(autopilot).state_ok


def test_start_up_refuses_unknown_parameters_and_bad_values_naming_them(tmp_path: Path):
    """The node exits with status 2 and a message naming the parameter (three nodes started at once)."""
    cases = {
        "-p controler:=combined": "unknown parameter 'controler'",
        "-p controller:=nope": "unknown controller 'nope'",
        "-p demand_altitude:=-5.0": "below the ground",
    }
    procs = {}
    for args, _ in cases.items():
        procs[args] = subprocess.Popen(
            [sys.executable, "-m", "lander_autopilot.node", "--ros-args", *args.split()],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for args, words in cases.items():
        out, _ = procs[args].communicate(timeout=60)
        assert procs[args].returncode == 2, out
        assert words in out, out
