"""One-line progress display for long runs: sim time, real-time factor, altitude.

Quiet unless the stream is a terminal (so logs, pipes and CI stay clean), and
redrawn at most ``rate`` times a second of wall time so it never costs the run.
"""
from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``\\r t 12.3 s | RTF 15.2x | alt 512.3 m`` on a terminal; nothing otherwise.

    Parameters
    ----------
    stream : text stream, default ``sys.stderr``
    enabled : bool or None
        ``None`` (default): on when ``stream.isatty()``.
    rate : float
        Maximum redraws per second of wall time.
    total : float or None
        Sim time [s] at which the run ends, shown as a percentage when given.
    """

    def __init__(
        self, stream: TextIO | None = None, enabled: bool | None = None, rate: float = 5.0, total: float | None = None
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, "isatty", lambda: False)
        self.enabled = bool(isatty()) if enabled is None else enabled
        self.period = 1.0 / rate
        self.total = total
        self._wall0: float | None = None
        self._sim0 = 0.0
        self._next = 0.0
        self._drawn = False

    def line(self, t_sim: float, wall_elapsed: float, altitude: float | None) -> str:
        """The text shown for sim time ``t_sim`` [s] after ``wall_elapsed`` [s] of wall time."""
        rtf = (t_sim - self._sim0) / wall_elapsed if wall_elapsed > 0 else 0.0
        parts = [f"t {t_sim:9.2f} s"]
        if self.total:
            parts[0] += f" ({min(100.0, 100.0 * t_sim / self.total):3.0f}%)"
        parts.append(f"RTF {rtf:7.1f}x")
        if altitude is not None:
            parts.append(f"alt {altitude:10.1f} m")
        return " | ".join(parts)

    def update(self, t_sim: float, altitude: float | None = None) -> None:
        """Record progress; redraws when enabled and the redraw period has passed."""
        now = time.monotonic()
        if self._wall0 is None:
            self._wall0, self._sim0 = now, t_sim
        if not self.enabled or now < self._next:
            return
        self._next = now + self.period
        self.stream.write("\r" + self.line(t_sim, now - self._wall0, altitude) + "\x1b[K")
        self.stream.flush()
        self._drawn = True

    def finish(self) -> None:
        """End the progress line so later output starts on a fresh line."""
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False
