"""What a new user meets with `lander fly` (parameter files, name checks, log noise, demands recorded), each as typed:

1. a demand published with default QoS from another process during a flight is in the bag;
3. a ``--params`` section the launcher does not know is a one-line error (exit 2), and the
   autopilot's package name ``lander_autopilot`` works as its section;
4. a bad scene, controller or flight name is one error line with the closest name, before any
   node starts;
5. no log noise: one line for a flapping gimbal lock (with a count), no start-up warning from the
   autopilot, no "paused at" line, scripted actions logged at the instant they apply.
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from lander_tools.fly.checks import read_params_file, resolve_controller
from lander_tools.fly.plan import SIM_NODE, FlightPlan, LaunchError
from lander_tools.fly.processes import node_commands

from .flightcheck import lander, lander_env
from .spancheck import read_span


def _lander(*args: str, timeout: float = 180.0) -> subprocess.CompletedProcess:
    return lander(*args, timeout=timeout)


# --- 1. every input is recorded, whatever QoS its publisher offers ------------------------------

_PUBLISHER = """
import sys, rclpy
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node("user_demand")
pub = node.create_publisher(Float64, "/lander/demand_altitude", 10)   # default QoS: reliable, volatile
msg = Float64(data=500.0)
node.create_timer(0.2, lambda: pub.publish(msg))
print("publishing", flush=True)
rclpy.spin(node)
"""


def test_a_demand_published_with_default_qos_is_recorded(tmp_path: Path) -> None:
    user = subprocess.Popen([sys.executable, "-c", _PUBLISHER], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=lander_env())
    try:
        assert user.stdout is not None and user.stdout.readline().strip() == "publishing"
        res = _lander("fly", "hover-canted", "--speed", "1", "--duration", "2", "--record", str(tmp_path / "B"),
                      "--no-progress")
    finally:
        user.terminate()
        user.wait(timeout=10)
    out = res.stdout + res.stderr
    assert res.returncode == 0, out
    assert "incompatible" not in out.lower(), out
    span = read_span(tmp_path / "B")
    # 2 s of flight at speed 1 while the user publishes every 0.2 s: about 10 messages. On the
    # old recorder (transient-local reader: no match with a volatile writer) there were none.
    assert span.counts["/lander/demand_altitude"] >= 5, span.counts


# --- 3. parameter-file sections ---------------------------------------------------------------


def test_params_file_sections_and_keys_are_checked(tmp_path: Path) -> None:
    good = tmp_path / "good.yaml"
    good.write_text("lander_autopilot:\n  ros__parameters:\n    demand_altitude: 520.0\n"
                    "lander_sim:\n  ros__parameters:\n    publish_rate: 20.0\n")
    assert read_params_file(good) == {"autopilot": {"demand_altitude": 520.0}, "lander_sim": {"publish_rate": 20.0}}
    for text, named in [("lander_autopilt:\n  ros__parameters: {demand_altitude: 1.0}\n", "'lander_autopilot'"),
                        ("autopilot:\n  ros__parameters: {demand_altitud: 1.0}\n", "'demand_altitude'"),
                        ("lander_sim:\n  ros__parameters: {speed: -1.0}\n", "'speed'"),
                        ("lander_sim:\n  parameters: {speed: 1.0}\n", "ros__parameters")]:
        bad = tmp_path / "bad.yaml"
        bad.write_text(text)
        with pytest.raises(LaunchError, match=named):
            read_params_file(bad)


def test_a_wrong_params_section_is_one_line_and_exit_2_and_lander_autopilot_works(tmp_path: Path) -> None:
    bad = tmp_path / "p.yaml"
    bad.write_text("lander_autopilt:\n  ros__parameters:\n    demand_altitude: 520.0\n")
    res = _lander("fly", "hover-canted", "--speed", "0", "--duration", "1", "--params", str(bad))
    assert res.returncode == 2
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "unknown section 'lander_autopilt'" in lines[0] and "allowed:" in lines[0], res.stderr
    assert "[sim]" not in res.stdout  # nothing was started
    good = tmp_path / "good.yaml"
    good.write_text("lander_autopilot:\n  ros__parameters:\n    demand_altitude: 520.0\n")
    res = _lander("fly", "hover-canted", "--speed", "0", "--duration", "0.5", "--params", str(good), "--no-progress")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "demand altitude 520.0 m" in res.stdout, res.stdout  # the autopilot's start-up line


def _sim_params(plan: FlightPlan, tmp_path: Path) -> dict:
    node_commands(plan, resolve_controller(plan), tmp_path)
    return yaml.safe_load((tmp_path / f"{SIM_NODE}.params.yaml").read_text())[SIM_NODE]["ros__parameters"]


def test_the_sims_lockstep_timeout_is_its_own_at_every_speed_unless_the_user_sets_one(tmp_path: Path) -> None:
    """`lander fly` gives the sim no lockstep timeout of its own at any speed: the autopilot
    answers every state within one period (the de-orbit MPC's reference at the handover too), so
    the node's one-period default stands; a user's or a scripted flight's value wins."""
    for plan in (FlightPlan(scene="deorbit-200km", controller="deorbit-mpc", speed=0.0),
                 FlightPlan(scene="hover-canted", speed=1.0), FlightPlan(scene="deorbit-200km", controller="none", speed=0.0)):
        assert "lockstep_timeout" not in _sim_params(plan, tmp_path)
    mine = tmp_path / "mine.yaml"
    mine.write_text("lander_sim:\n  ros__parameters:\n    lockstep_timeout: 0.5\n")
    assert _sim_params(FlightPlan(scene="deorbit-200km", speed=0.0, params_file=mine), tmp_path)["lockstep_timeout"] == 0.5
    scripted = FlightPlan(scene="deorbit-200km", speed=0.0, sim_params={"lockstep_timeout": 0.2})
    assert _sim_params(scripted, tmp_path)["lockstep_timeout"] == 0.2


# --- 4. names checked before anything starts --------------------------------------------------


@pytest.mark.parametrize("args,named", [
    (("hovr",), "did you mean 'hover'?"),
    (("hover", "--controller", "lqrr"), "did you mean 'lqr'?"),
    (("hover", "--controller", "nosuch"), "unknown controller 'nosuch'"),
    (("flights/seed2-scenario7-hovr.yaml",), "did you mean 'flights/seed2-scenario7-hover.yaml'?"),
    (("seed2-scenario7-hover",), "did you mean 'flights/seed2-scenario7-hover.yaml'?"),
])
def test_a_bad_name_is_one_error_line_before_anything_starts(args: tuple[str, ...], named: str) -> None:
    res = _lander("fly", *args, "--speed", "0", "--duration", "1")
    assert res.returncode == 2
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and named in lines[0], res.stderr
    assert "[sim]" not in res.stdout and "[fly]" not in res.stdout, res.stdout  # nothing was started


# --- 5. log noise -----------------------------------------------------------------------------


def test_a_flapping_gimbal_lock_is_reported_once_with_a_count() -> None:
    res = _lander("fly", "gimbal-lock-close", "--speed", "0", "--no-progress")
    assert res.returncode == 0, res.stdout + res.stderr
    events = [x for x in res.stdout.splitlines() if "gimbal lock" in x.lower() and "event at" in x]
    assert len(events) == 1, events
    m = re.search(r"gimbal lock: (\d+) events in all", res.stdout)
    assert m and int(m.group(1)) > 1, res.stdout  # the scene flaps in and out of the region many times


SCRIPT = """
name: quiet
scene: hover
speed: 0
sim: {publish_rate: 10.0}
end: {time: 2.0}
timeline:
  - {t: 0.95, demand_altitude: 505.0}
"""


def test_a_flight_logs_no_start_up_warning_no_pause_line_and_actions_at_their_instant(tmp_path: Path) -> None:
    (tmp_path / "quiet.yaml").write_text(SCRIPT)
    res = _lander("fly", str(tmp_path / "quiet.yaml"), "--no-progress")
    out = res.stdout + res.stderr
    assert res.returncode == 0, out
    assert "no state received yet" not in out, out
    assert "paused at" not in out, out
    # Due at 0.95 s, applied at the first control instant at or after it: 1.0 s (period 0.1 s).
    assert "[fly] t = 1.00 s: demand_altitude 505.0" in out, out
