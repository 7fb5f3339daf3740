"""Flights kept apart, over the real middleware (docs/flying.md, "Flights kept apart").

Two flights started at once on one machine, each with its own verbs, never see each other's
messages: each bag's flight topics are byte for byte those of the same flight flown alone. A
stranger publishing throttles to a flight is refused (the flight's states are those of the flight
flown alone), counted in the simulator's diagnostics and reported in one line. A flight another
simulator joins mid-way says so in one line, its autopilot does not answer the stranger's states
(its throttles are those of the flight flown alone) and its bag check names the extra messages;
a flight started in a domain where another flight runs is refused and leaves no bag, whether that
flight is another ``lander fly`` on this machine (the domain's lock) or a simulator started by hand
(the graph at start-up).

Every flight here is the same short hover (hover-canted, 20 s of sim time, lockstep), flown at 2x
or 4x real time where the test acts while it flies (flat out for the reference); the simulator's
lockstep_timeout is raised to 20 s, so a loaded machine cannot make it advance without the
autopilot's answer, and the flight is the same at any speed. The flight another simulator joins is
held paused (`lander pause`) until the launcher has seen the stranger, so the join is mid-way
however slowly the stranger starts.
"""
from __future__ import annotations

import os
import queue
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rosbags.rosbag2 import Reader

import rosutil

REPO = Path(__file__).resolve().parents[2]
DURATION = 20.0
STATES = 201  # t = 0 to 20 s at the scene's 10 Hz control rate
#: The flight's own topics: what must be byte for byte the same in any domain, alone or not
#: (/lander/events too, but for the wall-paced counts its FLIGHT_ENDED carries: flight_events).
FLIGHT_TOPICS = ("/clock", "/lander/state", "/lander/throttle", "/lander/events")
SAME_BYTES = ("/clock", "/lander/state", "/lander/throttle")
LAUNCH_TIMEOUT = 120.0  # a flight's start-up and end on two loaded cores; every wait ends at its event


@pytest.fixture(scope="module", autouse=True)
def own_run_files(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """This module's flights keep their run files (what a verb reads for "your flights") in a
    folder of their own, as one user's session would: flights of other tests or of the machine's
    user running meanwhile are not this user's flights here."""
    before = os.environ.get("XDG_RUNTIME_DIR")
    os.environ["XDG_RUNTIME_DIR"] = str(tmp_path_factory.mktemp("run"))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("XDG_RUNTIME_DIR", None)
        else:
            os.environ["XDG_RUNTIME_DIR"] = before


@pytest.fixture(scope="module")
def params_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("params") / "p.yaml"
    path.write_text("lander_sim:\n  ros__parameters:\n    lockstep_timeout: 20.0\n")
    return path


class Fly:
    """``lander fly`` as a process of its own; its output lines arrive in a queue as they come."""

    def __init__(self, bag: Path, params: Path, env: dict[str, str], speed: float = 2.0) -> None:
        self.bag = bag
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "lander_tools.cli", "fly", "hover-canted", "--duration", str(DURATION), "--speed",
             str(speed), "--params", str(params), "--record", str(bag), "--topics", *FLIGHT_TOPICS, "/diagnostics",
             "--no-progress"],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO, env=env)
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.log: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line)
        self.lines.put(None)

    def _take(self, timeout: float) -> Iterator[str]:
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                return
            if line is None:
                self.lines.put(None)
                return
            self.log.append(line)
            yield line

    def wait_line(self, pattern: str, timeout: float = LAUNCH_TIMEOUT) -> re.Match[str]:
        for line in self._take(timeout):
            m = re.search(pattern, line)
            if m:
                return m
        raise AssertionError(f"no line matching {pattern!r}:\n{self.text()}")

    def finish(self, timeout: float = LAUNCH_TIMEOUT) -> tuple[int, str]:
        for _ in self._take(timeout):
            pass
        try:
            rc = self.proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise
        return rc, self.text()

    def text(self) -> str:
        return "".join(self.log)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def flight_env(**changes: str | None) -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    for k, v in changes.items():
        if v is None:
            env.pop(k, None)
        else:
            env[k] = v
    return env


def raw_messages(bag: Path) -> dict[str, list[bytes]]:
    """The CDR bytes of every message per topic, in log order (an independent reader: rosbags)."""
    out: dict[str, list[bytes]] = {}
    with Reader(bag) as r:
        for conn, _t, raw in r.messages():
            out.setdefault(conn.topic, []).append(bytes(raw))
    return out


def flight_events(bag: Path) -> list[tuple[int, str, list[float]]]:
    """The flight's events, but for what FLIGHT_ENDED counts of the wall-paced topics (/diagnostics,
    /lander/markers: published once a wall second, so their counts depend on the flight's speed)."""
    from lander_interfaces.msg import FlightEvent
    from lander_ros.flight_span import COUNTED_TOPICS
    from lander_tools.bagio import read_bag

    wall = [2 + COUNTED_TOPICS.index(t) for t in ("/diagnostics", "/lander/markers")]
    out = []
    for m in read_bag(bag, ["/lander/events"]).messages("/lander/events"):
        values = [float(v) for v in m.values]
        if m.kind == FlightEvent.FLIGHT_ENDED:
            values = [v for i, v in enumerate(values) if i not in wall]
            out.append((int(m.kind), "", values))
        else:
            out.append((int(m.kind), str(m.detail), values))
    return out


def sim_rejections(bag: Path) -> dict[str, int]:
    """The simulator's rejection counters in its last /diagnostics of the flight."""
    from lander_ros.flight_span import sim_report
    from lander_tools.bagio import read_bag

    reports = [r for r in (sim_report(m) for m in read_bag(bag, ["/diagnostics"]).messages("/diagnostics")) if r]
    assert reports, "no report of the simulator in the bag"
    return {k: int(v) for k, v in reports[-1].items() if k.startswith("rejected.")}


@pytest.fixture(scope="module")
def alone(tmp_path_factory: pytest.TempPathFactory, params_file: Path) -> dict[str, Any]:
    """The flight flown alone, in this module's domain: the reference of every other flight here."""
    fly = Fly(tmp_path_factory.mktemp("alone") / "bag", params_file, flight_env(), speed=0.0)
    try:
        rc, out = fly.finish()
    finally:
        fly.kill()
    assert rc == 0 and "complete: every message" in out, out
    raw: dict[str, Any] = dict(raw_messages(fly.bag))
    assert len(raw["/lander/state"]) == STATES and len(raw["/lander/throttle"]) == STATES, out
    raw["events"] = flight_events(fly.bag)
    return raw


def test_two_flights_started_at_once_run_apart_each_with_its_own_verbs(alone, params_file: Path,
                                                                        tmp_path: Path) -> None:
    # No ROS_DOMAIN_ID: each launcher picks a domain no other flight or test run here holds.
    env = flight_env(ROS_DOMAIN_ID=None)
    flights = [Fly(tmp_path / name, params_file, env) for name in ("a", "b")]
    try:
        domains = [int(f.wait_line(r"^\[fly\] ROS_DOMAIN_ID=(\d+) \(picked free on this machine\), "
                                   r"discovery LOCALHOST").group(1)) for f in flights]
        assert domains[0] != domains[1]
        for f in flights:
            f.wait_line(r"^\[fly\] scene 'hover-canted'")
        # Each flight's verb, in its own domain; without one, a verb names both and takes the newest.
        # All at once (each is a Python process starting ROS: seconds on a loaded machine).
        verbs = [subprocess.Popen([sys.executable, "-m", "lander_tools.cli", "echo", "/lander/state", "--once",
                                   "--timeout", "60"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                  cwd=REPO, env=flight_env(ROS_DOMAIN_ID=str(d))) for d in domains]
        verbs.append(subprocess.Popen([sys.executable, "-m", "lander_tools.cli", "topics"], stdout=subprocess.PIPE,
                                      stderr=subprocess.PIPE, text=True, cwd=REPO, env=env))
        answers = [v.communicate(timeout=LAUNCH_TIMEOUT) for v in verbs]
        for v, (o, e) in zip(verbs[:2], answers[:2]):
            assert v.returncode == 0 and '"sequence"' in o, o + e
        (o, e), topics = answers[2], verbs[2]
        assert topics.returncode == 0 and "/lander/state" in o, o + e
        note = re.search(r"2 of your flights are running: this talks to the newest, 'hover-canted' in "
                         r"ROS_DOMAIN_ID=(\d+) \(others: 'hover-canted' in (\d+)", e)
        assert note and {int(note.group(1)), int(note.group(2))} == set(domains), e
        results = [f.finish() for f in flights]
    finally:
        for f in flights:
            f.kill()
    for (rc, out), f in zip(results, flights):
        assert rc == 0 and "complete: every message" in out and "EXTRA" not in out, out
        raw = raw_messages(f.bag)
        for topic in SAME_BYTES:
            assert raw.get(topic) == alone.get(topic), f"{topic} differs from the flight flown alone:\n{out}"
        assert flight_events(f.bag) == alone["events"], out


def test_a_stranger_publishing_throttles_is_refused_counted_and_reported(alone, params_file: Path, tmp_path: Path,
                                                                         ros_context) -> None:
    from rclpy.node import Node

    from lander_interfaces.msg import LanderState, ThrottleCommand

    obs = rosutil.Observer("stranger", context=ros_context)
    states = obs.record("/lander/state", LanderState, depth=1000)
    pub = obs.node.create_publisher(ThrottleCommand, "/lander/throttle", 10)
    assert isinstance(obs.node, Node)
    fly = Fly(tmp_path / "bag", params_file, flight_env(), speed=4.0)
    sent = 0
    try:
        obs.wait_for(lambda: bool(states), LAUNCH_TIMEOUT, "the flight's first state")

        # Every reader of the flight's throttles (the sim's, the launcher's watch and recorder; all
        # there once the flight runs) has matched this writer: a volatile writer's messages reach
        # only the readers matched when it sends, and the bag must hold what the sim refused.
        def all_readers_matched() -> bool:
            readers = obs.node.count_subscribers("/lander/throttle")
            return readers >= 2 and pub.get_subscription_count() >= readers

        obs.wait_for(all_readers_matched, LAUNCH_TIMEOUT, "every reader of /lander/throttle matched the stranger")
        # Full throttle on every thruster, from a node that is not the flight's, while the flight
        # flies: the flight must not feel it.
        while not any("throttle.stranger" in line for line in fly.log) and fly.proc.poll() is None:
            pub.publish(ThrottleCommand(state_sequence=0, throttles=[1.0] * len(states[-1].throttles)))
            sent += 1
            obs.spin_for(0.01)
            for _ in fly._take(0.01):
                pass
        rc, out = fly.finish()
    finally:
        fly.kill()
        obs.close()
    refusals = [line for line in out.splitlines() if "throttle.stranger" in line]
    assert len(refusals) == 1, out  # one line for the stranger, however many messages
    assert re.search(r"/lander/throttle from /stranger \(publisher [0-9a-f.]+\) refused: not of this flight",
                     refusals[0]), refusals[0]
    assert rc == 3 and re.search(r"EXTRA messages, another flight's: /lander/throttle \d+ of 201", out), out
    counted = sim_rejections(fly.bag).get("rejected.throttle.stranger", 0)
    assert 1 <= counted <= sent, (counted, sent)
    raw = raw_messages(fly.bag)
    for topic in ("/clock", "/lander/state"):
        assert raw[topic] == alone[topic], f"{topic}: the stranger's throttles changed the flight"


def test_a_flight_joined_mid_way_says_so_and_a_refused_flight_keeps_no_bag(alone, params_file: Path,
                                                                          tmp_path: Path, ros_context) -> None:
    from lander_interfaces.msg import LanderState

    obs = rosutil.Observer("watch", context=ros_context)
    states = obs.record("/lander/state", LanderState, depth=1000)
    fly = Fly(tmp_path / "bag", params_file, flight_env())
    joiner = refused = None
    try:
        obs.wait_for(lambda: bool(states), LAUNCH_TIMEOUT, "the flight's first state")
        # Held paused until the stranger has joined and been seen: the join is mid-way however long
        # the stranger's start-up takes on a loaded machine.
        paused = verb("pause")
        assert paused.returncode == 0, paused.stdout + paused.stderr
        obs.drain()
        held = len(states)  # from here on, states come from the stranger only
        # Someone else's simulator, running on its own (no launcher), and someone else's `lander fly`.
        joiner = rosutil.start_node("lander_sim.node", {"scene": "hover-canted", "speed": 1.0}, name="joiner")
        fly.wait_line(r"another flight joined")
        obs.wait_for(lambda: len(states) >= held + 3, LAUNCH_TIMEOUT, "the stranger's states")
        refused = Fly(tmp_path / "refused", params_file, flight_env(), speed=0.0)
        rc_refused, out_refused = refused.finish()
        # The stranger leaves, so that the flight's own simulator is the one /lander/resume reaches
        # (a service of two servers answers from one of them).
        joiner.close()
        joiner = None
        obs.wait_for(lambda: _nodes_named(obs, "lander_sim") == 1, LAUNCH_TIMEOUT, "the stranger gone from the graph")
        # Resumed through this test's node, which has the flight's simulator in its graph already.
        from std_srvs.srv import Trigger

        resume = obs.node.create_client(Trigger, "/lander/resume")
        resumed = obs.call(resume)
        assert resumed.success, resumed.message
        rc, out = fly.finish()
    finally:
        for f in (fly, refused):
            if f is not None:
                f.kill()
        if joiner is not None:
            joiner.close()
        obs.close()
    assert rc_refused == 2 and "another flight is running in ROS_DOMAIN_ID=" in out_refused, out_refused
    assert not (tmp_path / "refused").exists(), out_refused  # no bag of somebody else's messages
    joined = [line for line in out.splitlines() if "another flight joined" in line]
    assert len(joined) == 1, out
    extra = re.search(r"EXTRA messages, another flight's: (.*) published by this flight", out)
    assert rc == 3 and extra and "/clock" in extra.group(1) and "/lander/state" in extra.group(1), out
    # The flight's autopilot answered its own simulator only: its commands are those flown alone, in
    # order (the refused flight's autopilot, if it came up in time, may have added its own).
    assert _in_order_within(alone["/lander/throttle"], raw_messages(fly.bag)["/lander/throttle"]), out


def test_a_flight_is_refused_where_a_simulator_started_by_hand_runs(params_file: Path, tmp_path: Path,
                                                                    ros_context) -> None:
    """No ``lander fly`` holds the domain here: the refusal comes from the graph at start-up."""
    from lander_interfaces.msg import LanderState

    obs = rosutil.Observer("watch", context=ros_context)
    states = obs.record("/lander/state", LanderState, depth=10)
    by_hand = rosutil.start_node("lander_sim.node", {"scene": "hover-canted", "speed": 1.0}, name="by_hand")
    refused = None
    try:
        obs.wait_for(lambda: bool(states), LAUNCH_TIMEOUT, "the hand-started simulator's first state")
        refused = Fly(tmp_path / "refused", params_file, flight_env(), speed=0.0)
        rc, out = refused.finish()
    finally:
        if refused is not None:
            refused.kill()
        by_hand.close()
        obs.close()
    assert rc == 2 and "another flight is running in ROS_DOMAIN_ID=" in out, out
    assert not (tmp_path / "refused").exists(), out


def _nodes_named(obs: rosutil.Observer, name: str) -> int:
    return sum(1 for n, _ns in obs.node.get_node_names_and_namespaces() if n == name)


def verb(*argv: str) -> subprocess.CompletedProcess[str]:
    """A `lander` verb in the test's domain, as the user runs it."""
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", *argv, "--wait", "60"], capture_output=True,
                          text=True, cwd=REPO, env=flight_env(), timeout=LAUNCH_TIMEOUT)


def _in_order_within(wanted: list[bytes], got: list[bytes]) -> bool:
    it = iter(got)
    return all(any(w == g for g in it) for w in wanted)
