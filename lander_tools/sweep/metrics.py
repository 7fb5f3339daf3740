"""A flight's metrics and outcome from its samples at the control instants (one definition, two sources).

The core-only loop (:mod:`lander_tools.sweep.flight`) and a bag recorded through the ROS nodes
(:mod:`lander_tools.sweep.ros_path`) both reduce to :class:`Samples`, and :func:`evaluate` turns
samples into the row's outcome and metrics, so the two paths are compared on the same
definitions (``spec.METRICS``):

* ``hover_error``: RMS of ``altitude - demand`` over the last ``end.hover_window`` seconds flown;
* ``settling_time``: from the demand step until ``|error|`` stays within ``end.settle_band``;
* ``saturation_time``: controller updates that saturated times the control period;
* ``max_tilt``: largest angle between body z and the local vertical ``r_hat`` [rad];
* hover-hold sweeps (``end.hover_hold > 0``, :class:`HoverHold`): ``hover_time`` is the first
  control instant of the first run of instants with ``|altitude error| <= end.hover_band`` and
  ``|v_W| <= end.hover_speed`` lasting ``end.hover_hold``; the loop stops at the run's last instant;
* ``powered_fuel``: the fuel at the first instant the controller reported the mode
  ``powered-descent`` minus that at its first ``hover`` (the state each answer was computed from);
* ``powered_optimum``, ``fuel_ratio``: the minimum fuel from the state at that first ``powered-descent``
  to rest at the demand (core-only loop: :func:`lander_tools.sweep.flight.powered_optimum`), and the
  fuel flown from there to the first instant within ``end.hover_band`` and ``end.hover_speed`` of the
  hover over it (the optimum's own end: a law that hands over below the band, or too fast, has
  the hover law's climb back and braking counted, which ``powered_fuel`` leaves out). Read at that
  control instant: two errors of ~0.5 % of the optimum, of opposite signs, stay in it
  (:func:`band_entry_fuel`);
* ``powered_optimum_balanced``, ``fuel_ratio_balanced``: the same with the thrust bound the flown
  thrusters give with no torque (:func:`lander_autopilot.design.altitude.balanced_thrust`): a dispersed
  vehicle's attitude law takes a share of full throttle (not a strict bound: the canopy's torque can
  cancel the thrusters');
* ``compute_time``, ``mpc_solve_time_*``: measured by the loop, carried as they are (not deterministic).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_sim.physics.constants import MARS_RADIUS


@dataclass
class Samples:
    """What a flight looked like at its control instants ``t_k = k * period`` (SI, frames named).

    ``t``/``altitude_error``/``tilt``/``body_rate`` hold one entry per instant flown, up to and
    including the first state no longer flying (or the end); ``terminal`` is ``ok`` (flew to the
    end), ``crashed``, ``landed`` or ``diverged``.
    """

    t: np.ndarray
    altitude_error: np.ndarray  # [m]
    tilt: np.ndarray  # [rad]
    body_rate: np.ndarray  # |omega_B| [rad/s]
    fuel_start: float  # [kg]
    fuel_end: float  # [kg]
    saturated_updates: int
    period: float  # [s]
    touchdown_speed: float  # [m/s], NaN without touchdown
    terminal: str
    t_change: float  # [s] time of the demand step (0 without one)
    #: The simulator's touchdown figures: descent_rate, ground_speed [m/s], tilt_deg [deg], and
    #: classification (safe/hard/crash, from the event kind); empty without touchdown.
    touchdown: dict[str, Any] | None = None
    #: Total speed |v_W| at each instant [m/s] (the hover-hold criterion needs it; None: not recorded).
    speed: np.ndarray | None = None
    #: Fuel [kg] at the first instant the controller reported each mode (``ControlOutput.mode``).
    mode_fuel: dict[str, float] | None = None
    #: CPU seconds in the controller's update calls (``time.process_time``); NaN: not measured.
    compute_time: float = math.nan
    #: The controller's ``diagnostics()`` after the flight (e.g. ``mpc_solve_time_p99`` [s]).
    diagnostics: dict[str, float] | None = None
    #: Minimum fuel [kg] from the state at the first ``powered-descent`` to rest at the demand (NaN: not solved).
    powered_optimum: float = math.nan
    #: The same with the thrust the flown thrusters give with no torque (``balanced_thrust``); NaN: not solved.
    powered_optimum_balanced: float = math.nan
    #: Fuel [kg] at the first instant after that within ``end.hover_band`` and ``end.hover_speed`` of the
    #: hover (the optimum's end, at rest at the demand, to the band's tolerance); NaN: never.
    band_fuel: float = math.nan


def in_hover_band(altitude_error: float, speed: float, band: float, speed_limit: float) -> bool:
    """In the hover: ``|altitude error| <= band`` [m] and ``speed <= speed_limit`` [m/s] (the hover-hold
    criterion's instant, :class:`HoverHold`, and the fuel yardsticks' end, :func:`band_entry_fuel`)."""
    return abs(altitude_error) <= band and speed <= speed_limit


@dataclass(frozen=True)
class BandSample:
    """One control instant as the band's entry sees it: altitude error [m], speed ``|v_W|`` [m/s], fuel [kg]."""

    altitude_error: float
    speed: float
    fuel: float

    def within(self, band: float, speed_limit: float) -> bool:
        return in_hover_band(self.altitude_error, self.speed, band, speed_limit)


def band_entry_fuel(before: BandSample | None, at: BandSample, band: float, speed_limit: float) -> float:
    """The fuel [kg] at the first instant within ``band`` [m] of the demand at no more than
    ``speed_limit`` [m/s]: ``at`` is the first control instant where that holds, ``before`` the one
    before it (None: ``at`` is the first instant looked at, and its fuel is the answer).

    ``fuel_ratio`` reads the fuel at ``at`` itself; ``bench/deorbit_replay.py`` prints this one beside
    it (``fuel_ratio_entry``), and with ``--like`` this one over the optimum to the hover's tolerance
    (``fuel_ratio_like``). Read at the instant, the fuel counts the rest of the period's burn (0 to
    1.3 %, mean 0.5 % of the optimum); against that, the optimum at rest at the demand needs 0.5-0.9 %
    more than one ending within the band's tolerance. The two offset: over the sweeps' 800 flights the
    like-for-like ratio is 0.1-0.2 % over ``fuel_ratio`` in the mean, -0.4 to +0.8 % per flight
    (docs/deorbit.md, "The band's entry and the hover's tolerance").

    The throttles are held over the period, so the fuel falls linearly between the two instants; the
    altitude error is taken as linear too, and so is the speed's magnitude, which puts the speed's
    crossing at or after the true one (along a linearly changing velocity ``|v|`` is convex, under its
    chord): the entry's fuel is never understated. The instant is the later of the two crossings.
    """
    if before is None or before.within(band, speed_limit):
        return at.fuel
    s = 0.0
    e0, e1 = before.altitude_error, at.altitude_error
    if abs(e0) > band:  # e1 is within, so e0 != e1
        s = (e0 - math.copysign(band, e0)) / (e0 - e1)
    if before.speed > speed_limit:
        s = max(s, (before.speed - speed_limit) / (before.speed - at.speed))
    return before.fuel + min(max(s, 0.0), 1.0) * (at.fuel - before.fuel)


class HoverHold:
    """The hover-hold criterion, fed one control instant at a time (the loop's early stop and
    :func:`evaluate` use this one definition).

    An instant is *in* when ``|altitude error| <= band`` [m] and ``speed <= speed_limit`` [m/s]; the
    hover is held once the instants are in without a break from ``start`` to an instant at least
    ``hold`` [s] later. ``start`` is the first instant of the current run (None outside one).
    """

    def __init__(self, hold: float, band: float, speed_limit: float) -> None:
        self.hold, self.band, self.speed_limit = hold, band, speed_limit
        self.start: float | None = None
        self.held = False

    def update(self, t: float, altitude_error: float, speed: float) -> bool:
        """Feed the instant ``t`` [s]; True once (and from then on) the hover has been held."""
        if self.held:
            return True
        if in_hover_band(altitude_error, speed, self.band, self.speed_limit):
            if self.start is None:
                self.start = t
            self.held = t - self.start >= self.hold - 1e-9
        else:
            self.start = None
        return self.held

    @classmethod
    def of(cls, t: np.ndarray, altitude_error: np.ndarray, speed: np.ndarray, end: Any) -> HoverHold:
        """The criterion run over a flight's samples (stops feeding at the first held instant)."""
        h = cls(end.hover_hold, end.hover_band, end.hover_speed)
        for tk, ek, vk in zip(t, altitude_error, speed):
            if h.update(float(tk), float(ek), float(vk)):
                break
        return h


def altitude_and_tilt(r_W: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """Altitude above the Mars radius [m] and tilt of body z from the local vertical [rad].

    Both NaN at the planet's centre (``r_W = 0``): a fixed pivot (the seed-1 rotor scenes) has no
    local vertical and no altitude, so neither figure applies."""
    rn = math.sqrt(float(r_W @ r_W))
    if rn == 0.0:
        return math.nan, math.nan
    # body z in world coordinates, R(q)^T e_z: the third row of eq 13 (products by 0 and 1 are exact)
    s, a, b, c = q.tolist() if isinstance(q, np.ndarray) else q
    up = np.array([2.0 * (s * b + a * c), 2.0 * (b * c - s * a), s * s - a * a - b * b + c * c])
    return rn - MARS_RADIUS, math.acos(max(-1.0, min(1.0, float(up @ r_W) / rn)))


def evaluate(samples: Samples, end: Any) -> tuple[str, bool, dict[str, float]]:
    """``(outcome, success, metrics)`` of one flight judged by ``end`` (:class:`EndCondition`)."""
    s = samples
    e, t = np.asarray(s.altitude_error, dtype=float), np.asarray(s.t, dtype=float)
    flown = float(t[-1]) if t.size else 0.0
    window = t >= flown - end.hover_window
    hover = float(np.sqrt(np.mean(e[window] ** 2))) if e.size else math.nan
    max_tilt = float(np.max(s.tilt)) if len(s.tilt) else math.nan
    outcome = s.terminal
    if outcome == "ok":
        if max_tilt > end.max_tilt:
            outcome = "tipped"
        elif not hover <= end.max_hover_error:
            outcome = "off-target"
    success = outcome == "ok" or (outcome == "landed" and end.allow_touchdown)
    td = s.touchdown or {}
    td_rate, td_speed, td_tilt = (float(td.get(k, math.nan)) for k in ("descent_rate", "ground_speed", "tilt_deg"))
    if getattr(end, "land", False):
        outcome, success = _landing_outcome(s.terminal, td, td_rate, td_speed, td_tilt, end)
    hover_time = math.nan
    if getattr(end, "hover_hold", 0.0) > 0.0:
        if s.speed is None:
            raise ValueError("a hover-hold sweep needs the speed at each instant (Samples.speed)")
        hold = HoverHold.of(t, e, np.asarray(s.speed, dtype=float), end)
        if hold.held:
            hover_time = float(hold.start)  # type: ignore[arg-type]  # set when held
        outcome = s.terminal if s.terminal != "ok" else ("hovered" if hold.held else "no-hover")
        success = outcome == "hovered"
    mode_fuel = s.mode_fuel or {}
    diag = s.diagnostics or {}
    powered = (mode_fuel["powered-descent"] - mode_fuel["hover"]
               if "powered-descent" in mode_fuel and "hover" in mode_fuel else math.nan)
    to_band = mode_fuel.get("powered-descent", math.nan) - s.band_fuel  # [kg] the fuel the yardsticks measure
    metrics = {
        "touchdown_speed": s.touchdown_speed,
        "hover_error": hover,
        "final_altitude_error": float(e[-1]) if e.size else math.nan,
        "settling_time": settling_time(t, e, s.t_change, end.settle_band),
        "fuel_used": s.fuel_start - s.fuel_end if s.terminal != "diverged" else math.nan,
        "saturation_time": s.saturated_updates * s.period,
        "max_tilt": max_tilt,
        "max_body_rate": float(np.max(s.body_rate)) if len(s.body_rate) else math.nan,
        "flight_time": flown,
        "touchdown_descent_rate": td_rate,
        "touchdown_ground_speed": td_speed,
        "touchdown_tilt": td_tilt,
        "hover_time": hover_time,
        "fuel_left": s.fuel_end,
        "powered_fuel": powered,
        "powered_optimum": s.powered_optimum,
        "fuel_ratio": to_band / s.powered_optimum,
        "powered_optimum_balanced": s.powered_optimum_balanced,
        "fuel_ratio_balanced": to_band / s.powered_optimum_balanced,
        "compute_time": s.compute_time,
        "mpc_solve_time_p99": float(diag.get("mpc_solve_time_p99", math.nan)),
        "mpc_solve_time_median": float(diag.get("mpc_solve_time_median", math.nan)),
    }
    return outcome, success, metrics


def _landing_outcome(terminal: str, td: dict[str, Any], rate: float, speed: float, tilt_deg: float, end: Any) -> tuple[str, bool]:
    """Landing sweep: ``landed`` (safe and inside the sweep's limits), ``over-limits`` (safe for the
    scene, over the sweep's limits), ``hard-landing``, ``crashed``, ``no-touchdown`` or ``diverged``."""
    if terminal in ("ok", "diverged"):
        return ("no-touchdown" if terminal == "ok" else terminal), False
    cls = td.get("classification", "crash" if terminal == "crashed" else "safe")
    if cls != "safe":
        return ("hard-landing" if cls == "hard" else "crashed"), False
    inside = (rate < end.max_touchdown_descent_rate and speed < end.max_touchdown_ground_speed
              and math.radians(tilt_deg) < end.max_touchdown_tilt)
    return ("landed" if inside else "over-limits"), inside


def settled_index(e: np.ndarray, band: float) -> int | None:
    """First index from which ``|e|`` stays within ``band`` to the end; None if the last sample is outside."""
    outside = np.nonzero(np.abs(e) > band)[0]
    if outside.size == 0:
        return 0
    last = int(outside[-1])
    return None if last == e.size - 1 else last + 1


def settling_time(t: np.ndarray, e: np.ndarray, t_change: float, band: float) -> float:
    """Time from ``t_change`` until ``|e|`` stays within ``band`` to the end; NaN if it never does.

    The one definition of settling time: sweeps and :func:`lander_tools.analysis.metrics` use it.
    """
    after = t >= t_change
    if not np.any(after):
        return math.nan
    ta = t[after]
    i = settled_index(e[after], band)
    if i is None:
        return math.nan
    return 0.0 if i == 0 else float(ta[i] - t_change)
