"""Fly a shipped scripted flight, record it, and check the bag with two independent readers."""
from __future__ import annotations

import os
import queue
import re
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

from lander_tools.bagio import Bag, read_bag
from lander_tools.fly.plan import FlightResult
from lander_tools.scripted import load_script

from .spancheck import check_span

REPO = Path(__file__).resolve().parents[2]
#: What the flight tests record: the flight's own topics (not odometry/pose/markers, which the sim
#: only publishes when someone subscribes and which would only slow the test).
FLIGHT_TOPICS = ("/clock", "/lander/state", "/lander/throttle", "/lander/events",
                 "/lander/demand_altitude", "/lander/wind", "/autopilot/status")


def fly_shipped(name: str, tmp_path: Path, storage: str = "mcap") -> tuple[FlightResult, Path]:
    script = load_script(REPO / "flights" / f"{name}.yaml")
    script.topics = FLIGHT_TOPICS
    script.storage = storage
    bag = tmp_path / name
    result = script.run(record=bag)
    assert result.exit_code == 0, f"{name}: {result.outcome}: {result.message}"
    return result, bag


def mcap_counts(bag: Path) -> Counter:
    """Messages per topic decoded by the independent `mcap` + `mcap-ros2-support` reader, from the
    schemas embedded in the file (every message is decoded, not just counted)."""
    from mcap_ros2.reader import read_ros2_messages

    counts: Counter = Counter()
    for m in read_ros2_messages(str(next(bag.glob("*.mcap")))):
        assert m.ros_msg is not None
        counts[m.channel.topic] += 1
    return counts


def check_bag(bag_path: Path, result: FlightResult) -> Bag:
    """Both readers agree with what the recorder wrote; nothing the publishers sent is missing."""
    bag = read_bag(bag_path)
    assert not bag.warnings
    written = {t: n for t, n in result.counts.items() if n}
    assert {t: n for t, n in bag.counts().items() if n} == written
    if bag.storage == "mcap":
        assert dict(mcap_counts(bag_path)) == written
    # The whole flight, exactly (spancheck): state 1 at t = 0 to the end instant, nothing after,
    # the sim's counts, and in lockstep (autopilot, or this launcher piloting) every state answered once.
    counts = mcap_counts(bag_path) if bag.storage == "mcap" else Counter()
    if bag.storage == "mcap":
        with_autopilot = counts.get("/autopilot/status", 0) > 0
        check_span(bag_path, result.sim_time, lockstep=counts.get("/lander/throttle", 0) > 0,
                   sim_only_events=not with_autopilot)
    return bag


#: ``lander`` as a process of its own, run from this checkout (whatever is installed elsewhere).
LANDER = [sys.executable, "-m", "lander_tools.cli"]


def lander_env() -> dict[str, str]:
    """The environment a ``lander`` process runs in: this checkout on its path, and the test module's
    own ROS_DOMAIN_ID (read now: conftest's module fixture sets it after this module is imported)."""
    return dict(os.environ, PYTHONPATH=str(REPO))


def lander(*args: str, timeout: float = 240.0) -> subprocess.CompletedProcess:
    """``lander ARGS`` run to its end (:data:`LANDER`), its output captured; no traceback allowed."""
    res = subprocess.run([*LANDER, *args], check=False, capture_output=True, text=True, cwd=REPO, timeout=timeout,
                         env=lander_env())
    assert "Traceback" not in res.stdout + res.stderr, res.stdout + res.stderr
    return res


def start_fly(script: Path, bag: Path, *args: str) -> tuple[subprocess.Popen, queue.Queue[str | None]]:
    """``lander fly SCRIPT --record BAG --no-progress ARGS`` as a process of its own (signals reach it
    alone); its output lines arrive in the returned queue, then None at its end (:func:`wait_line`,
    :func:`drain`)."""
    proc = subprocess.Popen(
        [*LANDER, "fly", str(script), "--record", str(bag), "--no-progress", *args],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO, env=lander_env(),
    )
    lines: queue.Queue[str | None] = queue.Queue()

    def read() -> None:
        for line in proc.stdout:  # type: ignore[union-attr]
            lines.put(line)
        lines.put(None)  # the end of the output

    threading.Thread(target=read, daemon=True).start()
    return proc, lines


def _read_lines(lines: queue.Queue[str | None], timeout: float) -> Iterator[str]:
    """The output's lines as they arrive, until its end or ``timeout`` wall seconds; the end stays
    queued for the next reader."""
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = lines.get(timeout=left)
        except queue.Empty:
            return
        if line is None:
            lines.put(None)
            return
        yield line


def wait_line(lines: queue.Queue[str | None], pattern: str, log: list[str], timeout: float = 60.0) -> re.Match:
    """The first line matching ``pattern`` (every line read goes into ``log``); AssertionError after
    ``timeout`` wall seconds or the output's end without one."""
    for line in _read_lines(lines, timeout):
        log.append(line)
        if m := re.search(pattern, line):
            return m
    raise AssertionError(f"no line matching {pattern!r} within {timeout} s:\n" + "".join(log))


def drain(lines: queue.Queue[str | None], log: list[str], timeout: float = 30.0) -> str:
    """Everything logged and the rest of the output up to its end (at most ``timeout`` s), as one text."""
    log.extend(_read_lines(lines, timeout))
    return "".join(log)
