"""The autopilot's control-loop statistics and its ``/diagnostics`` report, in plain Python (no rclpy).

The node times each control update (the controller's ``update`` through
:meth:`~lander_autopilot.ros.slot.ControllerSlot.step`, wall clock) and hands the time here with the
state's sim time; :class:`LoopStats` keeps

* the control period [s]: the smallest positive difference between the sim times of consecutive
  states answered (the simulator publishes one state per control period; a state the node missed
  makes a difference of two periods, never less than one; a pause re-publishes the same instant:
  no difference);
* the compute time per period [s]: median and p99 over the last :data:`WINDOW` periods (what the
  loop does now), the maximum, the mean and the total over the whole flight;
* the periods and the overruns: periods whose compute exceeded the control period (a period's
  compute that came before the period was known is classified once it is).

:class:`ReportClock` says when a report is due, on the sim clock (:data:`REPORT_PERIOD`).
:func:`control_status` and :func:`controller_status` give the ``(level, message, values)`` of the
two ``DiagnosticStatus`` entries the node publishes (``lander_autopilot.ros.convert`` fills the
messages). docs/autopilot_node.md, "/diagnostics".
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: ``diagnostic_msgs/DiagnosticStatus`` levels.
OK, WARN, ERROR = 0, 1, 2
#: Periods in the rolling window of the median and p99 (100 s at 10 Hz).
WINDOW = 1000
#: Sim seconds between two reports (plus one at every mode change).
REPORT_PERIOD = 1.0


@dataclass(frozen=True)
class LoopSummary:
    """The control loop's figures at one instant (SI units; NaN where there is no sample yet)."""

    period: float  #: control period [s] (NaN until two states were answered)
    periods: int  #: control updates timed since the reset
    window: int  #: periods in the median / p99
    median: float  #: compute time per period [s], median over the window
    p99: float  #: the same, 99th percentile
    max: float  #: longest compute time of one period since the reset [s]
    mean: float  #: mean compute time since the reset [s]
    total: float  #: compute time since the reset [s]
    overruns: int  #: periods whose compute exceeded the control period


class LoopStats:
    """Compute time per control period and the control period itself, since the last :meth:`reset`."""

    def __init__(self, window: int = WINDOW) -> None:
        if window < 1:
            raise ValueError(f"window = {window}: at least one period")
        self._size = window
        self.period = math.nan
        self.reset()

    def reset(self, keep_period: bool = False) -> None:
        """Forget every sample (a flight reset; ``keep_period``: a controller swap, same simulator)."""
        if not keep_period:
            self.period = math.nan
        self.periods = 0
        self.overruns = 0
        self.max = math.nan
        self.total = 0.0
        self._window: deque[float] = deque(maxlen=self._size)
        self._last_t: float | None = None
        self._unclassified: list[float] = []

    def add(self, t: float, compute: float) -> None:
        """One control update: the state's sim time ``t`` [s] and the update's wall time ``compute`` [s]."""
        if self._last_t is not None and t > self._last_t:
            dt = round(t - self._last_t, 9)  # stamps are whole nanoseconds
            if dt > 0.0 and not dt >= self.period:  # also true while the period is NaN
                self.period = dt  # earlier periods keep the classification they got
                self.overruns += sum(1 for c in self._unclassified if c > dt)
                self._unclassified.clear()
        if self._last_t is None or t > self._last_t:
            self._last_t = t
        compute = float(compute)
        self.periods += 1
        self.total += compute
        self.max = compute if not compute <= self.max else self.max
        self._window.append(compute)
        if math.isnan(self.period):
            self._unclassified.append(compute)
        elif compute > self.period:
            self.overruns += 1

    def summary(self) -> LoopSummary:
        """The figures now (percentiles over the window: numpy's linear interpolation)."""
        w = np.fromiter(self._window, dtype=float, count=len(self._window))
        med, p99 = (float(np.percentile(w, 50)), float(np.percentile(w, 99))) if len(w) else (math.nan, math.nan)
        mean = self.total / self.periods if self.periods else math.nan
        return LoopSummary(self.period, self.periods, len(w), med, p99, self.max, mean, self.total, self.overruns)


class ReportClock:
    """When a report is due on the sim clock: at the first state at or after each multiple of
    ``period`` [s] (so at t = 0 after a reset), whatever the real-time factor."""

    def __init__(self, period: float = REPORT_PERIOD) -> None:
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"report period = {period!r}: must be a finite number of seconds > 0")
        self.period = period
        self.next = 0.0

    def reset(self) -> None:
        self.next = 0.0

    def due(self, t: float) -> bool:
        """True (and the next report is scheduled) when a report is due at sim time ``t`` [s]."""
        if t < self.next - 1e-9:
            return False
        self.next = (math.floor(t / self.period + 1e-9) + 1) * self.period
        return True


def _fmt(value: Any) -> str:
    """A diagnostic value: floats with 9 significant digits ("nan" where none), the rest as ``str``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return str(value)
    return f"{value:.9g}"


def format_gains(gains: Mapping[str, Any]) -> str:
    """Gains as one line, 5 significant digits: ``K_altitude [[0.13247, 0.26762]], ...`` ("" for none)."""

    def fmt(v: Any) -> str:
        a = np.asarray(v, dtype=float)
        if a.ndim == 0:
            return f"{float(a):.5g}"
        return "[" + ", ".join(fmt(x) for x in a) + "]"

    return ", ".join(f"{k} {fmt(v)}" for k, v in gains.items())


def control_status(s: LoopSummary, controller: str, mode: str, gains: str = "",
                   params: str = "") -> tuple[int, str, dict[str, str]]:
    """Level, message and values of the control-loop status: the controller, its ``gains`` in
    force (:func:`format_gains`) and the ``controller_params`` it was built with (YAML), the
    loop's figures. WARN when the p99 compute time exceeds the control period (the loop cannot
    keep up in real time)."""
    values = {
        "controller": controller,
        "gains": gains,
        "controller_params": params,
        "mode": mode,
        "control_period_s": _fmt(s.period),
        "compute_time_median_s": _fmt(s.median),
        "compute_time_p99_s": _fmt(s.p99),
        "compute_time_max_s": _fmt(s.max),
        "compute_time_mean_s": _fmt(s.mean),
        "compute_time_total_s": _fmt(s.total),
        "window_periods": _fmt(s.window),
        "periods": _fmt(s.periods),
        "overruns": _fmt(s.overruns),
    }
    if s.periods == 0:
        return OK, "no state answered yet", values
    if math.isnan(s.period):
        return OK, f"control period not known yet; median {_ms(s.median)}", values
    if s.p99 > s.period:
        return WARN, f"p99 compute {_ms(s.p99)} exceeds the control period {_ms(s.period)}", values
    return OK, f"median {_ms(s.median)}, p99 {_ms(s.p99)} of {_ms(s.period)}; {s.overruns} overruns", values


def controller_status(figures: Mapping[str, Any] | None, error: str = "") -> tuple[int, str, dict[str, str]]:
    """Level, message and values of a controller's own ``diagnostics()`` figures (its units, SI);
    ERROR with ``error`` when calling it failed."""
    if error:
        return ERROR, error, {}
    return OK, "the controller's own figures (SI units)", {str(k): _fmt(v) for k, v in (figures or {}).items()}


def _ms(seconds: float) -> str:
    return f"{1e3 * seconds:.3g} ms" if math.isfinite(seconds) else "n/a"
