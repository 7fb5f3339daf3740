"""Pacing sim time against the wall clock at a requested real-time factor.

Plain Python, no rclpy: the node asks :meth:`Pacer.wait_time` how long to
sleep (while serving callbacks) before the next control tick is due.
The schedule is absolute, anchored at one (wall, sim) instant, so timer jitter
does not accumulate: tick k is due at ``wall0 + (t_k - t0) / speed``.
"""
from __future__ import annotations

import math
import time


def steps_per_tick(dt: float, publish_rate: float) -> int:
    """Physics steps per publish tick: ``round(1 / (publish_rate dt))``, at least 1.

    The control period is then exactly ``steps * dt`` of sim time, so every tick
    ends on a physics step and /clock never shows a time the physics did not reach.
    """
    return max(1, int(round(1.0 / (publish_rate * dt))))


class Pacer:
    """Wall-clock schedule of ticks at real-time factor ``speed`` (0: as fast as possible).

    If the simulation falls more than ``max_lag`` wall seconds behind (a slow
    machine, a lockstep wait, a pause), the schedule is re-anchored rather than
    letting it race to catch up, which would run far above the requested speed.
    """

    def __init__(self, speed: float, period: float, max_lag: float = 0.1, clock=time.monotonic) -> None:
        self._clock = clock
        self.max_lag = max_lag
        self.speed = speed
        self._period = 0.0
        self.set_period(period)
        self._anchor_wall = 0.0
        self._anchor_sim = 0.0
        self._anchored = False
        #: Wall instant the next schedule starts from (set by :meth:`restart`); None: the first tick.
        self._start_wall: float | None = None
        #: Times the loop was found more than ``max_lag`` behind its schedule (at a tick or a stop).
        self.overruns = 0

    def set_speed(self, speed: float) -> None:
        """Change the real-time factor; the schedule restarts from the next tick."""
        self.speed = speed
        self._anchored = False
        self._start_wall = None

    def restart(self) -> None:
        """Start a new schedule now (a resume, reset or step service): the first tick is due one
        control period from this instant, so a loop that only gets to it later is behind and
        counted like any other (a resume answered, then the process starved of CPU)."""
        self._anchored = False
        self._start_wall = self._clock()

    def stop(self, t_next: float) -> None:
        """The loop stops (a pause) before the tick that would end at sim time ``t_next``; count
        an overrun if that tick was already more than ``max_lag`` overdue, so a loop that fell
        behind just before it stopped says so too."""
        if self.speed > 0.0 and (self._anchored or self._start_wall is not None):
            now = self._clock()
            self._anchor(now, t_next)  # restarted, its first tick not reached yet: due from the restart
            if now - self._due(t_next) > self.max_lag:
                self.overruns += 1
        self._anchored = False
        self._start_wall = None

    def wait_time(self, t_next: float) -> float:
        """Wall seconds until the tick that ends at sim time ``t_next`` is due (0: now)."""
        if self.speed <= 0.0:
            return 0.0
        now = self._clock()
        self._anchor(now, t_next)
        due = self._due(t_next)
        lag = now - due
        if lag > self.max_lag:
            self.overruns += 1
            self._anchor_wall = now
            self._anchor_sim = t_next
            return 0.0
        return max(0.0, due - now)

    def _anchor(self, now: float, t_next: float) -> None:
        """Anchor the schedule if it is not: the first tick after (re)starting, the one ending at
        ``t_next``, is due one control period from the restart (from ``now`` if none was made)."""
        if not self._anchored:
            self._anchor_wall = now if self._start_wall is None else self._start_wall
            self._anchor_sim = t_next - self._period
            self._anchored = True
            self._start_wall = None

    def _due(self, t_next: float) -> float:
        """Wall instant the tick ending at sim time ``t_next`` is due on the anchored schedule."""
        return self._anchor_wall + (t_next - self._anchor_sim) / self.speed

    def set_period(self, period: float) -> None:
        """Sim-time length of one control period [s]."""
        if not (period > 0.0 and math.isfinite(period)):
            raise ValueError(f"control period must be > 0 s, got {period!r}")
        self._period = period
        self._anchored = False
        self._start_wall = None
