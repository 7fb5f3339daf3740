"""Measuring a running stack (sim + autopilot + recorder): per-process CPU and memory from
``/proc``, the control loop's figures from a recorded bag, and one recorded ``lander fly`` run as
a user runs it. Used by ``bench/full_stack.py`` and the reliability tests (soak, determinism).

Figures, over the flying part (from the state after the reset to the flight's end time): the
achieved real-time factor (sim seconds per wall second, from the recorder's receive times); the
control-loop latency (recorder receive time of the command answering state N minus that of
state N: publish of the state -> controller -> command on the wire); CPU per process
(``/proc/<pid>/stat`` utime + stime) in % of one core and peak RSS (``/proc/<pid>/status``);
messages lost (state sequence gaps, states without their command, the sim's lockstep timeouts).
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lander_ros.flight_span import sim_report
from lander_ros.stamps import stamp_to_seconds

REPO = Path(__file__).resolve().parents[1]  # where `python -m lander_tools.cli` runs from

#: What the benchmark records: the control loop and what it needs to measure it.
TOPICS = ("/clock", "/lander/state", "/lander/throttle", "/autopilot/status", "/diagnostics")
_CLK_TCK = os.sysconf("SC_CLK_TCK")
_PID_LINE = re.compile(r"pids (.*)$")


# --- /proc readers (no psutil) ----------------------------------------------------------------


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time [s] of process ``pid`` so far, or None once it is gone.

    ``/proc/<pid>/stat``: the command name (field 2) may contain spaces, so fields are counted
    after its closing parenthesis; utime and stime are fields 14 and 15, in clock ticks.
    """
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    rest = text[text.rindex(")") + 2:].split()
    return (int(rest[11]) + int(rest[12])) / _CLK_TCK  # fields 14, 15 (rest starts at field 3)


def rss_bytes(pid: int) -> int | None:
    """Resident set size [bytes] of process ``pid`` (``VmRSS`` of ``/proc/<pid>/status``), or None."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    return None


@dataclass
class ProcSeries:
    """Samples of one process: wall time [s, time.time()], CPU seconds, RSS [bytes]."""

    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    rss: list[int] = field(default_factory=list)

    def cpu_percent(self, w0: float, w1: float) -> float:
        """Mean CPU use over wall window [w0, w1] in % of one core (interpolated samples)."""
        if len(self.wall) < 2 or w1 <= w0:
            return float("nan")
        c0, c1 = np.interp([w0, w1], self.wall, self.cpu)
        return 100.0 * (c1 - c0) / (w1 - w0)

    def rss_at(self, w: float) -> float:
        return float(np.interp(w, self.wall, self.rss)) if self.wall else float("nan")


class Sampler:
    """Samples CPU time and RSS of named processes every ``period`` s in a background thread."""

    def __init__(self, period: float = 0.1) -> None:
        self.period = period
        self.pids: dict[str, int] = {}
        self.series: dict[str, ProcSeries] = {}
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def watch(self, name: str, pid: int) -> None:
        with self._lock:
            self.pids[name] = pid
            self.series.setdefault(name, ProcSeries())

    def sample(self) -> None:
        now = time.time()
        with self._lock:
            for name, pid in self.pids.items():
                c, r = cpu_seconds(pid), rss_bytes(pid)
                if c is not None and r is not None:
                    s = self.series[name]
                    s.wall.append(now)
                    s.cpu.append(c)
                    s.rss.append(r)

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            self.sample()

    def stop(self) -> dict[str, ProcSeries]:
        self._stop.set()
        self._thread.join()
        return self.series


# --- one flight ---------------------------------------------------------------------------------


@dataclass
class LoopFigures:
    """What a recorded lockstep flight says about its control loop (see the module docstring)."""

    sim_s: float
    wall_s: float
    rtf: float
    states: int
    states_missing: int
    commands_missing: int
    lockstep_timeouts: int | None
    latency_ms_p50: float
    latency_ms_p99: float
    latency_ms_max: float
    window_wall: tuple[float, float]
    #: Longest gap between two states' receive times at the recorder while flying [ms]: the
    #: longest stall a writer history must outlast (rate x stall, lander_ros.delivery).
    rx_gap_ms_max: float = float("nan")


def loop_figures(bag_path: Path) -> LoopFigures:
    """Analyse the control loop of a recorded lockstep flight (``lander fly --record``)."""
    from lander_tools.bagio import read_bag

    bag = read_bag(bag_path, list(TOPICS))
    st = bag.topics["/lander/state"]
    seq = np.array([m.sequence for m in st.messages], dtype=np.int64)
    t = np.array([stamp_to_seconds(m.header.stamp) for m in st.messages])
    rx = st.t_bag_ns.astype(np.float64) * 1e-9
    start = int(np.flatnonzero(seq == 1)[-1])  # the launcher's reset: the flight proper
    end_t = float(bag.meta.get("end_time", t[-1]))
    keep = np.arange(len(seq)) >= start
    keep &= t <= end_t + 1e-9
    seq, t, rx = seq[keep], t[keep], rx[keep]
    missing = int(seq[-1] - seq[0] + 1 - len(np.unique(seq)))
    answered: dict[int, float] = {}
    thr = bag.topics.get("/lander/throttle")
    if thr is not None:
        for m, r in zip(thr.messages, thr.t_bag_ns):
            answered.setdefault(int(m.state_sequence), float(r) * 1e-9)
    # The state that ended the flight is not answered (the launcher stops the autopilot there).
    lat = np.array([answered[s] - r for s, r in zip(seq[:-1], rx[:-1]) if s in answered])
    commands_missing = int(len(seq) - 1 - len(lat))
    timeouts = None
    diag = bag.topics.get("/diagnostics")
    sim_reports = [r for m in (diag.messages if diag is not None else []) if (r := sim_report(m)) is not None]
    if sim_reports and "lockstep_timeouts" in sim_reports[-1]:
        timeouts = int(sim_reports[-1]["lockstep_timeouts"])
    # RTF over the stepping part: from the first state at t > 0 (the reset's state 1 at t = 0 waits for the resume).
    moving = np.flatnonzero(t > 0.0)
    i0 = max(int(moving[0]) - 1, 0) if len(moving) else 0
    sim_s, wall_s = float(t[-1] - t[i0]), float(rx[-1] - rx[i0])

    def q(p: float) -> float:  # latency percentile [ms]
        return float(np.percentile(lat, p)) * 1e3 if len(lat) else float("nan")

    flying = rx[i0 + 1:]  # from the first step on (the reset-to-resume wait is no stall)
    gap = float(np.diff(flying).max()) * 1e3 if len(flying) > 1 else float("nan")
    return LoopFigures(sim_s, wall_s, sim_s / wall_s if wall_s > 0 else float("nan"), len(seq), missing,
                       commands_missing, timeouts, q(50), q(99), q(100), (float(rx[i0]), float(rx[-1])), gap)


def fly_recorded(scene: str, duration: float, compose: bool, bag: Path, env: dict[str, str] | None = None,
                 extra: tuple[str, ...] = (), sampler: Sampler | None = None, timeout: float = 600.0) -> tuple[int, str]:
    """Run ``lander fly SCENE --speed 0 --duration D --record BAG`` (lockstep), watching its processes.

    Returns (exit code, output). Processes are registered in ``sampler`` as ``launcher+recorder``,
    ``sim``, ``autopilot`` or ``composed`` as soon as the launcher prints their pids.
    """
    argv = [sys.executable, "-m", "lander_tools.cli", "fly", scene, "--speed", "0", "--duration", str(duration),
            "--record", str(bag), "--no-progress", "--topics", *TOPICS, *(("--compose",) if compose else ()), *extra]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO,
                            env=env if env is not None else os.environ.copy())
    if sampler is not None:
        sampler.watch("launcher+recorder", proc.pid)
    lines: list[str] = []
    # Over time: SIGINT (the launcher stops its nodes and closes the bag), SIGKILL if that hangs
    # (the nodes then die with the launcher: lander_tools.child).
    timer = threading.Timer(timeout, proc.send_signal, args=(signal.SIGINT,))
    killer = threading.Timer(timeout + 30.0, proc.kill)
    timer.start()
    killer.start()
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            m = _PID_LINE.search(line)
            if m and sampler is not None:
                for part in m.group(1).split(","):
                    name, pid = part.split()
                    sampler.watch(name, int(pid))
        rc = proc.wait()
    finally:
        timer.cancel()
        killer.cancel()
    return rc, "".join(lines)
