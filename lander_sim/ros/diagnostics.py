"""Health figures of the simulation node and their ``diagnostic_msgs`` form.

:class:`NodeHealth` is plain Python (counters and timing statistics) so it can be
unit-tested; :func:`to_diagnostic_status` turns it into one
``diagnostic_msgs/DiagnosticStatus`` per publication.
"""
from __future__ import annotations

import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: DiagnosticStatus levels (``diagnostic_msgs/DiagnosticStatus``: OK=0, WARN=1, ERROR=2).
OK, WARN, ERROR = 0, 1, 2

#: |q| - 1 above which the integrator's quaternion drift is reported as a warning.
QUAT_DRIFT_WARN = 1e-6
#: States whose publish time is remembered for matching commands (a ring indexed by sequence).
LATENCY_RING = 64
#: Control-loop latency samples kept for the percentiles (the most recent ones).
LATENCY_SAMPLES = 2000


@dataclass
class NodeHealth:
    """Counters and timings the node accumulates; reset only by a restart of the node.

    ``rejected`` counts every refused input by kind (``"throttle.nan"``,
    ``"wind.non_finite"``, ``"service.load_scene"``, ...), so a test or operator
    sees each one even when the log lines are throttled.
    """

    rejected: Counter = field(default_factory=Counter)
    physics_steps: int = 0
    ticks: int = 0
    step_wall_s: float = 0.0  # wall time spent inside Simulation.step [s]
    lockstep_timeouts: int = 0
    stale_commands: int = 0
    commands_accepted: int = 0
    _window_wall: float = field(default_factory=time.monotonic)
    _window_sim: float = 0.0
    rtf: float = 0.0  # real-time factor achieved over the last diagnostics window
    #: Control-loop latencies [s, wall]: state published -> first command answering it received.
    latencies: deque = field(default_factory=lambda: deque(maxlen=LATENCY_SAMPLES))
    _ring_seq: list = field(default_factory=lambda: [0] * LATENCY_RING)
    _ring_wall: list = field(default_factory=lambda: [0.0] * LATENCY_RING)

    def state_published(self, sequence: int, wall: float) -> None:
        """Remember when state ``sequence`` went out (monotonic wall clock [s])."""
        i = sequence % LATENCY_RING
        self._ring_seq[i], self._ring_wall[i] = sequence, wall

    def forget_published(self) -> None:
        """A reset restarts the sequence: answers to the old numbers must not match the new states."""
        self._ring_seq[:] = [0] * LATENCY_RING

    def command_received(self, state_sequence: int, wall: float) -> None:
        """A command answering ``state_sequence`` was accepted at ``wall``: one latency sample.

        Only the first answer to a state counts (the slot is cleared), and only while the
        state is among the last :data:`LATENCY_RING` published (older answers, or answers
        to a previous reset epoch's numbers, find another sequence in the slot).
        """
        i = state_sequence % LATENCY_RING
        if self._ring_seq[i] == state_sequence and state_sequence != 0:
            self.latencies.append(wall - self._ring_wall[i])
            self._ring_seq[i] = 0

    def latency_percentiles(self) -> tuple[float, float] | None:
        """(p50, p95) of the kept control-loop latencies [s], or None without samples."""
        if not self.latencies:
            return None
        p50, p95 = np.percentile(np.fromiter(self.latencies, float, len(self.latencies)), (50.0, 95.0))
        return float(p50), float(p95)

    def reject(self, kind: str) -> int:
        """Count one rejected input of ``kind``; returns the new count of that kind."""
        self.rejected[kind] += 1
        return self.rejected[kind]

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def update_rtf(self, sim_time: float, now: float | None = None) -> float:
        """Real-time factor achieved since the last call: sim seconds per wall second."""
        now = time.monotonic() if now is None else now
        wall = now - self._window_wall
        if wall > 0.0:
            # A reset makes sim time jump back; that window reports 0 rather than a negative rate.
            self.rtf = max(0.0, (sim_time - self._window_sim) / wall)
        self._window_wall, self._window_sim = now, sim_time
        return self.rtf

    def restart_window(self, sim_time: float) -> None:
        """Start a new RTF window at ``sim_time`` (after a reset or scene load)."""
        self._window_wall, self._window_sim = time.monotonic(), sim_time

    @property
    def mean_step_us(self) -> float:
        """Mean wall time of one physics step [microseconds]."""
        return 1e6 * self.step_wall_s / self.physics_steps if self.physics_steps else 0.0


def to_diagnostic_status(status, health: NodeHealth, *, name: str, hardware_id: str, extra: dict[str, str]) -> None:
    """Fill a ``diagnostic_msgs/DiagnosticStatus`` from ``health`` plus ``extra`` key/values.

    Level: ERROR if the integrator's |q| drift exceeds :data:`QUAT_DRIFT_WARN` by
    1000x, WARN for any rejected input, stale command, lockstep timeout or a
    drift above the warning level, OK otherwise.
    """
    from diagnostic_msgs.msg import KeyValue  # deferred: keeps this module importable without ROS

    drift = abs(float(extra.get("quaternion_norm_drift", "0") or 0.0))
    level, msg = OK, "running"
    if health.rejected_total or health.stale_commands or health.lockstep_timeouts or drift > QUAT_DRIFT_WARN:
        level, msg = WARN, "inputs rejected, stale commands, lockstep timeouts or |q| drift: see values"
    if drift > 1000 * QUAT_DRIFT_WARN:
        level, msg = ERROR, f"integrator health: |q| drift {drift:.3g}"
    status.level = bytes([level]) if isinstance(status.level, bytes) else level
    status.name = name
    status.message = msg
    status.hardware_id = hardware_id
    values = {
        "physics_steps": str(health.physics_steps),
        "ticks": str(health.ticks),
        "mean_step_time_us": f"{health.mean_step_us:.3f}",
        "real_time_factor": f"{health.rtf:.3f}",
        "commands_accepted": str(health.commands_accepted),
        "rejected_total": str(health.rejected_total),
        "lockstep_timeouts": str(health.lockstep_timeouts),
        "stale_commands": str(health.stale_commands),
    }
    lat = health.latency_percentiles()
    values["control_latency_samples"] = str(len(health.latencies))
    values["control_latency_p50_ms"] = "n/a" if lat is None else f"{1e3 * lat[0]:.3f}"
    values["control_latency_p95_ms"] = "n/a" if lat is None else f"{1e3 * lat[1]:.3f}"
    values.update({f"rejected.{k}": str(v) for k, v in sorted(health.rejected.items())})
    values.update(extra)
    status.values = [KeyValue(key=k, value=v) for k, v in values.items()]


def diagnostics_array(health: NodeHealth, *, t: float, name: str, hardware_id: str, extra: dict[str, str]) -> Any:
    """A ``diagnostic_msgs/DiagnosticArray`` stamped at sim time ``t`` [s] with one status, filled by
    :func:`to_diagnostic_status` from ``health`` plus ``extra``."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # deferred, as above

    from lander_ros.stamps import fill_stamp

    arr = DiagnosticArray()
    fill_stamp(arr.header.stamp, t)
    status = DiagnosticStatus()
    to_diagnostic_status(status, health, name=name, hardware_id=hardware_id, extra=extra)
    arr.status = [status]
    return arr
