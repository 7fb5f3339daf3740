"""How `lander fly` ends: the sim node killed mid-flight leaves a valid bag holding everything up
to the kill and exit status 2; Ctrl-C stops the flight cleanly with a valid bag (status 130); a
launcher killed outright takes its nodes with it (none is left flying on the domain)."""
from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
from pathlib import Path

import numpy as np
import psutil

from lander_tools.bagio import read_bag

from .flightcheck import FLIGHT_TOPICS, drain, mcap_counts, start_fly, wait_line

SCRIPT = """
name: long-spin
scene: free-spin
controller: none
speed: 5.0
sim: {publish_rate: 10.0}
end: {time: 300.0}
timeline:
  - {t: 3.0, throttle: [0.0, 0.1, 0.0, 0.0]}
"""


def _start(tmp_path: Path) -> tuple[subprocess.Popen, queue.Queue[str | None], Path]:
    (tmp_path / "long.yaml").write_text(SCRIPT)
    bag = tmp_path / "bag"
    proc, lines = start_fly(tmp_path / "long.yaml", bag, "--topics", *FLIGHT_TOPICS)
    return proc, lines, bag


def _check_prefix_bag(bag: Path, t_min: float) -> None:
    b = read_bag(bag)
    assert not b.warnings
    counts = {t: n for t, n in b.counts().items() if n}
    assert dict(mcap_counts(bag)) == counts
    s = b.series("/lander/state")
    seq = s["sequence"].astype(np.int64)
    start = int(np.flatnonzero(seq == 1)[-1])
    # Everything the sim published after the reset, without a gap, up to where it stopped.
    np.testing.assert_array_equal(seq[start:], np.arange(1, len(seq) - start + 1))
    assert s["t"][-1] >= t_min


def test_killing_the_sim_mid_flight_leaves_a_valid_bag_and_status_2(tmp_path: Path) -> None:
    proc, lines, bag = _start(tmp_path)
    log: list[str] = []
    try:
        pid = int(wait_line(lines, r"pids sim (\d+)", log).group(1))
        wait_line(lines, r"\[fly\] t = 3\.00 s: throttle", log)  # the flight is under way
        os.kill(pid, signal.SIGKILL)
        rc = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    out = drain(lines, log)
    assert rc == 2, out
    assert "node process 'sim' exited with code -9" in out
    _check_prefix_bag(bag, 3.0)
    assert read_bag(bag).meta["outcome"] == "error"


def test_ctrl_c_stops_cleanly_with_a_valid_bag_and_status_130(tmp_path: Path) -> None:
    proc, lines, bag = _start(tmp_path)
    log: list[str] = []
    try:
        wait_line(lines, r"\[fly\] t = 3\.00 s: throttle", log)
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert rc == 130, "".join(log)
    _check_prefix_bag(bag, 3.0)
    assert read_bag(bag).meta["outcome"] == "interrupted"


def test_a_launcher_killed_outright_takes_its_nodes_with_it(tmp_path: Path) -> None:
    # The nodes run in a session of their own (Ctrl-C reaches only the launcher); without
    # lander_tools.child a SIGKILLed launcher left them flying, in lockstep at full speed.
    proc, lines, _ = _start(tmp_path)
    log: list[str] = []
    try:
        m = wait_line(lines, r"pids (.*)$", log)
        pids = [int(p) for p in re.findall(r"\d+", m.group(1))]
        wait_line(lines, r"\[fly\] t = 3\.00 s: throttle", log)
        nodes = [psutil.Process(p) for p in pids]
        proc.kill()
        proc.wait(timeout=10)
        # Each node gets SIGTERM from the kernel and exits cleanly; 30 s covers its 1 s flush.
        _, alive = psutil.wait_procs(nodes, timeout=30.0)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not alive, f"nodes still running after their launcher was killed: {alive}\n" + "".join(log)
