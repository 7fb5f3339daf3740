"""Metrics of recorded flights (no rclpy; bags are read with :mod:`lander_tools.bagio`).

:class:`Flight` turns a bag into numpy arrays (simulation time, world-frame
position/velocity, attitude, body rates, throttles, demand altitude, events).
:func:`metrics` computes the numbers users compare flights by, :func:`table` and :func:`to_json`
put several flights side by side; :mod:`lander_tools.analysis_plots` draws the standard figures.

A metric is ``None`` (printed "n/a") where the flight's scene cannot produce it; the rules, shared
with the flight summary of ``lander fly``, are :mod:`lander_tools.metrics_fit`'s.

Metric definitions (all SI):

* ``outcome``: ``landed`` / ``crashed`` (from ``/lander/events`` or the last state's
  ``phase``), else ``flying`` (the flight ended on its time limit).
* ``touchdown_speed``: the speed the simulator reported with LANDED/CRASHED, else
  ``|v_W|`` of the first state no longer flying.
* ``touchdown_*``: the touchdown event's figures: ``touchdown_class`` (safe / hard / crash against
  the scene's ``touchdown`` limits), descent rate and ground speed [m/s], tilt [deg], fuel left [kg].
* ``fuel_used``: first minus last ``fuel_mass`` [kg]; n/a for a vehicle without thrusters.
* ``final_altitude``: the last state's altitude [m]; n/a for a fixed pivot.
* Demand timeline: the demand altitude in force as ``/autopilot/status`` reports it (first
  value and each change, timed at the state the autopilot first answered with it), so the
  scene's demand counts too; bags without that field fall back to ``/lander/demand_altitude``.
* Step response to the demand altitude ``h_d`` (reference 2, section 4.1): for the
  last step of the demand timeline to a hover (or the first demand, if it never changed) over
  its segment, which ends at the next change or at the touchdown. A demand of 0 m or less asks
  the autopilot to land (the landing and de-orbit laws), not to hover: a flight that lands on
  demand is measured on the hover before it, and a landing-only flight has no step response
  (its figures are the touchdown's). A law that reports its mode (the guided descents: landing,
  de-orbit) hovers only in :data:`HOVER_MODE`: the segment starts at its first status in that
  mode, and a flight that never got there (a de-orbit still in orbit) has no step response.
  In the step's segment,
  ``settling_time`` is the time after the step from which ``|h - h_d|`` stays inside
  ``band = max(2 % of the step, band_min)`` (:func:`lander_tools.sweep.metrics.settling_time`,
  the sweeps' definition; ``None`` where it never settles); ``overshoot`` is the largest excursion
  past ``h_d`` in the step's direction as a percentage of the step; ``steady_state_error``
  is the mean of ``h - h_d`` and ``hover_error_max`` the largest ``|h - h_d|`` over the last
  ``tail_fraction`` of the settled part of the segment: from the instant after which the error
  stays within ``band_min`` to its end, else from the settling instant, else the whole segment,
  so that a long approach (a de-orbit's fall from orbit to a hover) does not count as the steady
  state. ``band_min`` first, because 2 % of a de-orbit's step is no hover measure: from scenario
  0's orbit (a 677 km step) it is 13.5 km, and a hover of 37 s before a landing demand put 2.4 s
  of the braking in the tail (1.9 m mean, 48.7 m largest, for a hover held within 1 m).
* ``saturation_time``: simulation time the autopilot reported ``saturated`` outside a landing
  law's :data:`COAST_MODE` (or, without ``/autopilot/status``, time with any throttle at 0 or 1
  while others are not); n/a without thrusters or without an autopilot.
* ``gimbal_lock_events``: the simulator's GIMBAL_LOCK events, as ``lander fly`` counts them
  (:func:`lander_tools.metrics_fit.gimbal_lock_count`); for a bag without ``/lander/events``, the
  entries into the state's flag in Euler mode (:func:`~lander_tools.metrics_fit.gimbal_lock_entries`),
  n/a if the scene is unknown too.
* ``quaternion_norm_drift``: ``max ||q| - 1|`` of the published attitude; n/a for an Euler-mode
  scene, whose quaternion is made from the angles for publishing, not integrated.
* ``angular_momentum_drift``: relative drift of the world-frame angular momentum
  ``L_W = R(q)^T I omega_B`` (dynamics reference eq 2, 13), ``max |L_W - L_W(t0)| / |L_W(t0)|``
  over each torque-free span (:func:`lander_tools.metrics_fit.torque_free`: no thrust, stabiliser,
  chute, ground contact or torquing scene model), the worst span; conserved there, so any drift
  is integration error. n/a where no state is torque-free or the scene is unknown.
  ``I = m diag(k^2)`` with the lander's radii of gyration unless the scene's vehicle says otherwise.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from lander_ros.stamps import stamp_to_seconds
from lander_sim.physics import constants
from lander_sim.physics.rotation import quat_to_matrix
from lander_tools.bagio import Bag, BagError
from lander_tools.metrics_fit import (
    SceneFacts,
    altitude_applies,
    fuel_applies,
    gimbal_lock_count,
    gimbal_lock_entries,
    scene_facts,
    torque_free,
)
from lander_tools.sweep.metrics import settled_index, settling_time

# FlightEvent kinds (lander_interfaces/msg/FlightEvent.msg); duplicated as plain ints so that
# analysis needs neither rclpy nor the built interfaces.
EV_LANDED, EV_CRASHED, EV_GIMBAL_LOCK, EV_CONTROLLER_SWITCHED = 0, 1, 2, 7
EV_HARD_LANDING = 9  # FlightEvent.msg: over the scene's safe touchdown limits, under its crash limits
EV_FLIGHT_ENDED = 12  # FlightEvent.msg: the sim's end of the flight, with its counts (lander_ros.flight_span)
PHASE_NAMES = {0: "flying", 1: "landed", 2: "crashed"}


@dataclass
class Flight:
    """Time series of one recorded flight. Times are simulation time [s]."""

    name: str
    t: np.ndarray  #: (N,) state times
    r_W: np.ndarray  #: (N, 3) position, world frame [m]
    v_W: np.ndarray  #: (N, 3) velocity, world frame [m/s]
    q: np.ndarray  #: (N, 4) core quaternion (s, x, y, z), world -> body
    euler: np.ndarray  #: (N, 3) ZXZ angles [rad]
    omega_B: np.ndarray  #: (N, 3) body rates [rad/s]
    altitude: np.ndarray
    climb_rate: np.ndarray
    mass: np.ndarray
    fuel: np.ndarray
    throttles: np.ndarray  #: (N, n_thrusters)
    phase: np.ndarray
    gimbal_lock: np.ndarray
    sequence: np.ndarray
    demand_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    demand: np.ndarray = field(default_factory=lambda: np.zeros(0))
    events: list[tuple[float, int, str, list[float]]] = field(default_factory=list)
    status_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    status_saturated: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    meta: dict[str, str] = field(default_factory=dict)
    parachute: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  #: (N,) chute out
    stabiliser: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  #: (N,) stabiliser on
    #: the autopilot's mode at each status (the guided descent laws' phases; "" for the others)
    status_mode: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    events_recorded: bool = True  #: the bag recorded /lander/events (an empty event list is then a fact)

    @property
    def facts(self) -> SceneFacts | None:
        """What the flight's scene has (:mod:`lander_tools.metrics_fit`), ``None`` if unknown."""
        return scene_facts(self.meta)

    @classmethod
    def from_bag(cls, bag: Bag, name: str | None = None) -> Flight:
        """Extract a flight from a bag; raises :class:`BagError` if it has no ``/lander/state``."""
        if "/lander/state" not in bag:
            raise BagError(f"{bag.path}: no /lander/state messages, so no flight to analyse (topics: {bag.counts()})")
        s = bag.series("/lander/state")
        # A reset restarts the sequence at 1: the flight is what follows the last reset.
        restarts = np.flatnonzero(np.diff(s["sequence"].astype(np.int64)) <= 0)
        if len(restarts):
            k = int(restarts[-1] + 1)
            s = {key: v[k:] for key, v in s.items()}
        end = bag.meta.get("end_time")
        if end is not None:
            # States the sim produced after the launcher saw the flight end, while stopping.
            keep = s["t"] <= float(end) + 1e-9
            s = {key: v[keep] for key, v in s.items()}
        q_ros = np.column_stack([s["orientation.w"], s["orientation.x"], s["orientation.y"], s["orientation.z"]])
        f = cls(
            name=name or bag.path.name,
            t=s["t"],
            r_W=np.column_stack([s["position.x"], s["position.y"], s["position.z"]]),
            v_W=np.column_stack([s["velocity.x"], s["velocity.y"], s["velocity.z"]]),
            q=q_ros,
            euler=s["euler_zxz"],
            omega_B=np.column_stack([s["angular_velocity.x"], s["angular_velocity.y"], s["angular_velocity.z"]]),
            altitude=s["altitude"],
            climb_rate=s["climb_rate"],
            mass=s["mass"],
            fuel=s["fuel_mass"],
            throttles=s["throttles"],
            phase=s["phase"].astype(int),
            gimbal_lock=s["gimbal_lock"].astype(bool),
            sequence=s["sequence"].astype(np.int64),
            meta=dict(bag.meta),
            parachute=s.get("parachute_deployed", np.zeros(len(s["t"]))).astype(bool),
            stabiliser=s.get("stabiliser_on", np.zeros(len(s["t"]))).astype(bool),
            events_recorded="/lander/events" in bag.topics,
        )
        for m in bag.messages("/lander/events"):
            f.events.append((stamp_to_seconds(m.header.stamp), int(m.kind), m.detail, list(m.values)))
        if "/autopilot/status" in bag:
            st = bag.series("/autopilot/status")
            f.status_t, f.status_saturated = st["t"], st["saturated"].astype(bool)
            f.status_mode = np.asarray(st["mode"], dtype=str) if "mode" in st else np.full(len(st["t"]), "")
            if "demand_altitude" in st:  # bags recorded before the status carried it have no column
                f.demand_t, f.demand = _demand_changes(st["t"], st["demand_altitude"].astype(float), end)
        if not len(f.demand) and "/lander/demand_altitude" in bag:
            d = bag.series("/lander/demand_altitude")
            f.demand_t, f.demand = d["t"], d["data"].astype(float)
        return f

    def demand_at(self, t: np.ndarray) -> np.ndarray:
        """Demand altitude in force at times ``t`` (zero-order hold; NaN before the first)."""
        out = np.full(len(t), np.nan)
        if len(self.demand):
            idx = np.searchsorted(self.demand_t, t, side="right") - 1
            ok = idx >= 0
            out[ok] = self.demand[idx[ok]]
        return out

    def z_axis_track(self) -> np.ndarray:
        """Body z axis in world coordinates, ``R(q)[2, :]`` (eq 13): Figure 1 of reference 1."""
        return np.array([quat_to_matrix(q)[2, :] for q in self.q])


def _demand_changes(t: np.ndarray, demand: np.ndarray, end: str | None) -> tuple[np.ndarray, np.ndarray]:
    """The demand timeline from the autopilot's status: its first value and every change.

    ``t`` are the stamps of the states the autopilot answered, so a change is timed at the first
    control instant that flew it. Status from before the last reset (time runs backwards) and
    after the flight's end (``end``, the bag's ``end_time``) is dropped, as for the states.
    """
    back = np.flatnonzero(np.diff(t) < 0)
    keep = np.arange(len(t)) >= (int(back[-1]) + 1 if len(back) else 0)
    if end is not None:
        keep &= t <= float(end) + 1e-9
    t, demand = t[keep], demand[keep]
    if not len(t):
        return t, demand
    change = np.concatenate(([True], demand[1:] != demand[:-1]))
    return t[change], demand[change]


@dataclass
class Metrics:
    """The numbers of one flight; ``None`` where a metric does not apply (see module docstring)."""

    name: str
    duration: float
    states: int
    outcome: str
    touchdown_speed: float | None
    fuel_used: float | None
    final_altitude: float | None
    demand_altitude: float | None
    step_size: float | None
    settling_time: float | None
    overshoot_percent: float | None
    steady_state_error: float | None
    hover_error_max: float | None
    saturation_time: float | None
    gimbal_lock_events: int | None
    quaternion_norm_drift: float | None
    angular_momentum_drift: float | None
    controller_switches: int
    final_spin_rate: float
    #: The touchdown event's figures (None without touchdown): classification against the
    #: scene's limits (safe / hard / crash), descent rate [m/s], ground speed [m/s], tilt [deg], fuel left [kg].
    touchdown_class: str | None = None
    touchdown_descent_rate: float | None = None
    touchdown_ground_speed: float | None = None
    touchdown_tilt: float | None = None
    touchdown_fuel_left: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _inertia_diag(flight: Flight) -> np.ndarray:
    """Principal moments (N, 3) along the flight [kg m^2]."""
    scene = flight.meta.get("scene")
    if scene:
        try:
            from lander_sim.scenes import load_scene

            vehicle = load_scene(scene).vehicle
            return np.array([vehicle.inertia(f) for f in flight.fuel])
        except Exception:  # noqa: BLE001, S110 - scene library missing or scene renamed: fall back
            pass
    return flight.mass[:, None] * np.asarray(constants.LANDER_GYRATION_SQ)[None, :]


def angular_momentum_W(flight: Flight) -> np.ndarray:
    """World-frame angular momentum ``R(q)^T I omega_B`` (eq 2, 13), shape (N, 3)."""
    I = _inertia_diag(flight)
    h_B = I * flight.omega_B
    return np.array([quat_to_matrix(q).T @ h for q, h in zip(flight.q, h_B)])


def _step_response(
    t: np.ndarray, h: np.ndarray, t0: float, h0: float, hd: float, band_min: float, tail_fraction: float
) -> tuple[float | None, float | None, float | None, float]:
    sel = t >= t0
    ts, hs = t[sel], h[sel]
    if len(ts) < 2:
        return None, None, None, float("nan")
    step = hd - h0
    band = max(0.02 * abs(step), band_min)
    err = hs - hd
    st = settling_time(ts, err, t0, band)
    settling = None if math.isnan(st) else st  # NaN: never settled within the recorded segment
    overshoot = None
    if abs(step) > band_min:
        past = np.sign(step) * err
        overshoot = float(max(0.0, past.max()) / abs(step) * 100.0)
    # The tail is taken from the settled part: a de-orbit's segment is a half-hour fall to a
    # two-minute hover, and the last 20 % of the whole segment would average the fall in. Settled
    # within band_min first: the 2 % band of a step from orbit is kilometres wide.
    start = settled_index(err, band_min)
    if start is None:
        start = settled_index(err, band)
    settled = err if start is None else err[start:]
    n_tail = max(1, int(len(settled) * tail_fraction))
    sse = float(np.mean(settled[-n_tail:]))
    return settling, overshoot, sse, float(np.max(np.abs(settled[-n_tail:])))


def _hover_step(demand: np.ndarray, demand_t: np.ndarray, t_down: float) -> int | None:
    """Index in the demand timeline of the step whose response is measured (module docstring):
    the last change to a hover demand (> 0 m) before the touchdown, else the first demand if it
    is a hover; ``None`` if the flight never had one."""
    hover = (demand > 0.0) & (demand_t < t_down)
    if not hover.any():
        return None
    changes = np.nonzero(hover[1:] & (np.diff(demand) != 0))[0] + 1
    return int(changes[-1]) if len(changes) else int(np.argmax(hover))


#: The autopilot's mode while a guided descent law (de-orbit: lander_autopilot.controllers.deorbit.phases)
#: holds its hover; its other modes fly a descent towards the demand, not a step to it.
HOVER_MODE = "hover"
#: The landing laws' unpowered mode: they ask for no thrust by design, so a command clipped at
#: zero there is the law's, not a limit reached (lander_autopilot.controllers.landing.MODES).
COAST_MODE = "coast"


def _hovering_from(flight: Flight, t0: float, t1: float) -> float | None:
    """When the lander starts hovering on the demand set at ``t0`` (segment ends ``t1``): at once for
    laws that report no mode (the hover laws), else at the first status in :data:`HOVER_MODE`
    (the guided descents report their phase); ``None`` if that never came within the segment."""
    modes = flight.status_mode
    if not len(modes) or not np.any(modes != ""):
        return t0
    hover = (modes == HOVER_MODE) & (flight.status_t >= t0) & (flight.status_t < t1)
    return float(flight.status_t[np.argmax(hover)]) if hover.any() else None


def _saturation_time(flight: Flight, n_thrusters: int) -> float | None:
    """Time [s] the autopilot reported its command clipped (outside a coast, :data:`COAST_MODE`);
    without its status, the time with some throttles at a limit and others not. ``None`` where
    nothing can saturate: no thrusters, or no autopilot (bag metadata ``controller: none``)."""
    if n_thrusters == 0 or flight.meta.get("controller") == "none":
        return None
    if len(flight.status_t) > 1:
        dt = np.diff(flight.status_t)
        clipped = flight.status_saturated.copy()
        if len(flight.status_mode) == len(clipped):
            clipped &= flight.status_mode != COAST_MODE
        return float(np.sum(dt[clipped[:-1]]))
    if len(flight.t) > 1 and flight.throttles.size:
        thr = flight.throttles
        at_limit = np.any((thr <= 0.0) | (thr >= 1.0), axis=1) & ~np.all(thr <= 0.0, axis=1)
        return float(np.sum(np.diff(flight.t)[at_limit[:-1]]))
    return 0.0


def metrics(flight: Flight, band_min: float = 0.5, tail_fraction: float = 0.2) -> Metrics:
    """Compute :class:`Metrics` of a flight (definitions in the module docstring).

    ``band_min`` [m] is the smallest settling band; ``tail_fraction`` the final part of the
    step segment over which the steady-state error is averaged.
    """
    t = flight.t
    n = len(t)
    outcome = PHASE_NAMES.get(int(flight.phase[-1]), "flying") if n else "flying"
    touchdown: float | None = None
    touchdown_time: float | None = None  # [s] of sim time
    td: dict[str, Any] = {}
    for _, kind, _, values in flight.events:
        if kind in (EV_LANDED, EV_HARD_LANDING, EV_CRASHED):
            outcome = "crashed" if kind == EV_CRASHED else "landed"
            # values: t_impact [s], descent_rate [m/s], ground_speed [m/s], tilt_deg, fuel_left [kg]
            touchdown = math.hypot(values[1], values[2]) if len(values) >= 3 else None
            touchdown_time = float(values[0]) if len(values) else None
            td = dict(zip(("touchdown_descent_rate", "touchdown_ground_speed", "touchdown_tilt", "touchdown_fuel_left"),
                          (float(v) for v in values[1:5])))
            td["touchdown_class"] = {EV_LANDED: "safe", EV_HARD_LANDING: "hard"}.get(kind, "crash")
            break
    if touchdown is None and outcome != "flying":
        k = int(np.argmax(flight.phase != 0))
        touchdown = float(np.linalg.norm(flight.v_W[max(k - 1, 0)]))
        touchdown_time = float(t[k])

    # Step response: the last step to a hover, over its segment (module docstring).
    settling = overshoot = sse = hover_max = step = hd = None
    t_down = touchdown_time if touchdown_time is not None else math.inf
    facts = flight.facts
    # Free space or a fixed pivot: no altitude to hold (metrics_fit), whatever demand the status names.
    ks = _hover_step(flight.demand, flight.demand_t, t_down) if facts is None or facts.surface else None
    if ks is not None:
        hd = float(flight.demand[ks])
        t1 = min(float(flight.demand_t[ks + 1]) if ks + 1 < len(flight.demand) else math.inf, t_down)
        # A guided descent that never reached its hover has no step to measure (None).
        t0 = _hovering_from(flight, float(flight.demand_t[ks]), t1)
        if t0 is not None:
            # The step is measured from where the lander actually was when the demand changed
            # (after a guided descent: when its hover began).
            h0 = float(np.interp(t0, t, flight.altitude))
            step = hd - h0
            seg = t <= t1
            settling, overshoot, sse, hover_max = _step_response(
                t[seg], flight.altitude[seg], t0, h0, hd, band_min, tail_fraction)

    n_thr = facts.n_thrusters if facts is not None else (flight.throttles.shape[1] if flight.throttles.ndim == 2 else 0)
    sat_time = _saturation_time(flight, n_thr)

    # One definition with `lander fly` (metrics_fit): the sim's GIMBAL_LOCK events.
    gl_events: int | None = gimbal_lock_count(e[1] for e in flight.events)
    if not flight.events_recorded:
        gl_events = gimbal_lock_entries(flight.gimbal_lock, facts.attitude) if facts is not None else None

    qn: float | None = float(np.max(np.abs(np.linalg.norm(flight.q, axis=1) - 1.0))) if n else 0.0
    if facts is not None and facts.attitude == "euler":
        qn = None
    l_drift = None
    stab = flight.stabiliser if len(flight.stabiliser) == n else np.zeros(n, dtype=bool)
    chute = flight.parachute if len(flight.parachute) == n else np.zeros(n, dtype=bool)
    free = torque_free(flight.throttles, stab, chute, flight.phase, facts) if n > 1 else np.zeros(n, dtype=bool)
    if free.any():
        L = angular_momentum_W(flight)
        # Each contiguous thrust-free span conserves its own L_W; report the worst span.
        edges = np.flatnonzero(np.diff(np.concatenate(([0], free.astype(int), [0]))))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a > 1:
                L0 = np.linalg.norm(L[a])
                if L0 > 0:
                    d = float(np.max(np.linalg.norm(L[a:b] - L[a], axis=1)) / L0)
                    l_drift = d if l_drift is None else max(l_drift, d)

    return Metrics(
        name=flight.name,
        duration=float(t[-1] - t[0]) if n else 0.0,
        states=n,
        outcome=outcome,
        touchdown_speed=touchdown,
        fuel_used=float(flight.fuel[0] - flight.fuel[-1]) if n and fuel_applies(n_thr) else None,
        final_altitude=float(flight.altitude[-1]) if n and altitude_applies(flight.r_W[-1], facts) else None,
        demand_altitude=hd,
        step_size=step,
        settling_time=settling,
        overshoot_percent=overshoot,
        steady_state_error=sse,
        hover_error_max=hover_max,
        saturation_time=sat_time,
        gimbal_lock_events=gl_events,
        quaternion_norm_drift=qn,
        angular_momentum_drift=l_drift,
        controller_switches=sum(1 for e in flight.events if e[1] == EV_CONTROLLER_SWITCHED),
        final_spin_rate=float(np.linalg.norm(flight.omega_B[-1])) if n else 0.0,
        **td,
    )


# --- output -----------------------------------------------------------------------------------


def _fmt(v: Any) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return f"{v:.6g}"
    return str(v)


_UNITS = {
    "duration": "s", "touchdown_speed": "m/s", "fuel_used": "kg", "final_altitude": "m",
    "demand_altitude": "m", "step_size": "m", "settling_time": "s", "overshoot_percent": "%",
    "steady_state_error": "m", "hover_error_max": "m", "saturation_time": "s",
    "final_spin_rate": "rad/s", "touchdown_descent_rate": "m/s", "touchdown_ground_speed": "m/s",
    "touchdown_tilt": "deg", "touchdown_fuel_left": "kg",
}


def table(all_metrics: list[Metrics]) -> str:
    """A plain-text table, one column per flight, plus a difference column for two flights."""
    rows = [k for k in all_metrics[0].as_dict() if k != "name"]
    header = ["metric"] + [m.name for m in all_metrics]
    if len(all_metrics) == 2:
        header.append("difference (2 - 1)")
    lines = []
    for r in rows:
        vals = [getattr(m, r) for m in all_metrics]
        label = f"{r} [{_UNITS[r]}]" if r in _UNITS else r
        line = [label] + [_fmt(v) for v in vals]
        if len(all_metrics) == 2:
            a, b = vals
            line.append(_fmt(b - a) if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool) else "")
        lines.append(line)
    widths = [max(len(str(x)) for x in col) for col in zip(header, *lines)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    out = [fmt.format(*header), fmt.format(*["-" * w for w in widths])]
    out += [fmt.format(*line) for line in lines]
    return "\n".join(out)


def differences(all_metrics: list[Metrics]) -> dict[str, dict[str, float]]:
    """Numeric metric differences of every flight against the first: ``{name: {metric: diff}}``."""
    base = all_metrics[0].as_dict()
    out: dict[str, dict[str, float]] = {}
    for m in all_metrics[1:]:
        d = {}
        for k, v in m.as_dict().items():
            b = base[k]
            if isinstance(v, (int, float)) and isinstance(b, (int, float)) and not isinstance(v, bool):
                d[k] = float(v - b)
        out[m.name] = d
    return out


def to_json(all_metrics: list[Metrics], extra: dict[str, Any] | None = None) -> str:
    """JSON for scripts: ``{"flights": [...], "differences": {...}}`` plus the keys of ``extra``
    (``lander analyse --reference`` adds ``"reference"``); NaN written as null."""

    def clean(x: Any) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        return x

    doc = {"flights": [clean(m.as_dict()) for m in all_metrics]}
    if len(all_metrics) > 1:
        doc["differences"] = clean(differences(all_metrics))
    for key, value in (extra or {}).items():
        doc[key] = [clean(v) for v in value] if isinstance(value, list) else clean(value)
    return json.dumps(doc, indent=2)
