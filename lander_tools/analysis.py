"""Metrics and plots of recorded flights (no rclpy; bags are read with :mod:`lander_tools.bagio`).

:class:`Flight` turns a bag into numpy arrays (simulation time, world-frame
position/velocity, attitude, body rates, throttles, demand altitude, events).
:func:`metrics` computes the numbers users compare flights by, :func:`write_plots`
draws the standard figures to PNG and :func:`compare` puts several flights side by side.

Metric definitions (all SI):

* ``outcome``: ``landed`` / ``crashed`` (from ``/lander/events`` or the last state's
  ``phase``), else ``flying`` (the flight ended on its time limit).
* ``touchdown_speed``: the speed the simulator reported with LANDED/CRASHED, else
  ``|v_W|`` of the first state no longer flying.
* ``fuel_used``: first minus last ``fuel_mass`` [kg].
* Step response to the demand altitude ``h_d`` (reference 2, section 4.1): for the
  last step of the demand timeline (or the first demand heard, if it never changed),
  ``settling_time`` is the time after the step from which ``|h - h_d|`` stays inside
  ``band = max(2 % of the step, band_min)``; ``overshoot`` is the largest excursion
  past ``h_d`` in the step's direction as a percentage of the step; ``steady_state_error``
  is the mean of ``h - h_d`` over the last ``tail_fraction`` of the segment.
* ``saturation_time``: simulation time the autopilot reported ``saturated`` (or, without
  ``/autopilot/status``, time with any throttle at 0 or 1 while others are not).
* ``gimbal_lock_events``: GIMBAL_LOCK events, else rising edges of the state's flag.
* ``quaternion_norm_drift``: ``max ||q| - 1|`` of the published attitude.
* ``angular_momentum_drift``: relative drift of the world-frame angular momentum
  ``L_W = R(q)^T I omega_B`` (dynamics reference eq 2, 13) over spans where every
  throttle is zero; conserved for torque-free flight, so any drift is integration
  error. ``I = m diag(k^2)`` with the lander's radii of gyration unless the scene's
  vehicle (from the bag's ``scene`` metadata) says otherwise.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lander_sim.physics import constants
from lander_sim.physics.rotation import quat_to_matrix
from lander_tools.bagio import Bag, BagError

# FlightEvent kinds (lander_interfaces/msg/FlightEvent.msg); duplicated as plain ints so that
# analysis needs neither rclpy nor the built interfaces.
EV_LANDED, EV_CRASHED, EV_GIMBAL_LOCK, EV_CONTROLLER_SWITCHED = 0, 1, 2, 7
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

    @classmethod
    def from_bag(cls, bag: Bag, name: str | None = None) -> "Flight":
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
        )
        if "/lander/demand_altitude" in bag:
            d = bag.series("/lander/demand_altitude")
            f.demand_t, f.demand = d["t"], d["data"].astype(float)
        for m in bag.messages("/lander/events"):
            f.events.append((m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, int(m.kind), m.detail, list(m.values)))
        if "/autopilot/status" in bag:
            st = bag.series("/autopilot/status")
            f.status_t, f.status_saturated = st["t"], st["saturated"].astype(bool)
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


@dataclass
class Metrics:
    """The numbers of one flight; ``None`` where a metric does not apply (see module docstring)."""

    name: str
    duration: float
    states: int
    outcome: str
    touchdown_speed: float | None
    fuel_used: float
    final_altitude: float
    demand_altitude: float | None
    step_size: float | None
    settling_time: float | None
    overshoot_percent: float | None
    steady_state_error: float | None
    hover_error_max: float | None
    saturation_time: float
    gimbal_lock_events: int
    quaternion_norm_drift: float
    angular_momentum_drift: float | None
    controller_switches: int
    final_spin_rate: float

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
        except Exception:  # noqa: BLE001 - scene library missing or scene renamed: fall back
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
    outside = np.nonzero(np.abs(err) > band)[0]
    if len(outside) == 0:
        settling: float | None = 0.0
    elif outside[-1] == len(ts) - 1:
        settling = None  # never settled within the recorded segment
    else:
        settling = float(ts[outside[-1] + 1] - t0)
    overshoot = None
    if abs(step) > band_min:
        past = np.sign(step) * err
        overshoot = float(max(0.0, past.max()) / abs(step) * 100.0)
    n_tail = max(1, int(len(ts) * tail_fraction))
    sse = float(np.mean(err[-n_tail:]))
    return settling, overshoot, sse, float(np.max(np.abs(err[-n_tail:])))


def metrics(flight: Flight, band_min: float = 0.5, tail_fraction: float = 0.2) -> Metrics:
    """Compute :class:`Metrics` of a flight (definitions in the module docstring).

    ``band_min`` [m] is the smallest settling band; ``tail_fraction`` the final part of the
    step segment over which the steady-state error is averaged.
    """
    t = flight.t
    n = len(t)
    outcome = PHASE_NAMES.get(int(flight.phase[-1]), "flying") if n else "flying"
    touchdown = None
    for _, kind, _, values in flight.events:
        if kind in (EV_LANDED, EV_CRASHED):
            outcome = "landed" if kind == EV_LANDED else "crashed"
            touchdown = float(values[0]) if values else None
            break
    if touchdown is None and outcome != "flying":
        k = int(np.argmax(flight.phase != 0))
        touchdown = float(np.linalg.norm(flight.v_W[max(k - 1, 0)]))

    # Step response: the last change of the demand, else the first demand heard.
    settling = overshoot = sse = hover_max = step = hd = None
    if len(flight.demand):
        changes = np.nonzero(np.abs(np.diff(flight.demand)) > 0)[0]
        k = int(changes[-1] + 1) if len(changes) else 0
        t0, hd = float(flight.demand_t[k]), float(flight.demand[k])
        # The step is measured from where the lander actually was when the demand changed.
        h0 = float(np.interp(t0, t, flight.altitude))
        step = hd - h0
        settling, overshoot, sse, hover_max = _step_response(t, flight.altitude, t0, h0, hd, band_min, tail_fraction)

    # Saturation time.
    if len(flight.status_t) > 1:
        dt = np.diff(flight.status_t)
        sat_time = float(np.sum(dt[flight.status_saturated[:-1]]))
    elif n > 1 and flight.throttles.size:
        thr = flight.throttles
        at_limit = np.any((thr <= 0.0) | (thr >= 1.0), axis=1) & ~np.all(thr <= 0.0, axis=1)
        sat_time = float(np.sum(np.diff(t)[at_limit[:-1]]))
    else:
        sat_time = 0.0

    gl_events = sum(1 for e in flight.events if e[1] == EV_GIMBAL_LOCK)
    if gl_events == 0 and n:
        gl_events = int(flight.gimbal_lock[0]) + int(np.sum(flight.gimbal_lock[1:] & ~flight.gimbal_lock[:-1]))

    qn = float(np.max(np.abs(np.linalg.norm(flight.q, axis=1) - 1.0))) if n else 0.0
    l_drift = None
    if n > 1 and flight.throttles.size:
        free = np.all(np.nan_to_num(flight.throttles) == 0.0, axis=1)
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
        fuel_used=float(flight.fuel[0] - flight.fuel[-1]) if n else 0.0,
        final_altitude=float(flight.altitude[-1]) if n else float("nan"),
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
    )


# --- output -----------------------------------------------------------------------------------


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        return f"{v:.6g}"
    return str(v)


_UNITS = {
    "duration": "s", "touchdown_speed": "m/s", "fuel_used": "kg", "final_altitude": "m",
    "demand_altitude": "m", "step_size": "m", "settling_time": "s", "overshoot_percent": "%",
    "steady_state_error": "m", "hover_error_max": "m", "saturation_time": "s",
    "final_spin_rate": "rad/s",
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


def to_json(all_metrics: list[Metrics]) -> str:
    """JSON for scripts: ``{"flights": [...], "differences": {...}}``; NaN written as null."""

    def clean(x: Any) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        return x

    doc = {"flights": [clean(m.as_dict()) for m in all_metrics]}
    if len(all_metrics) > 1:
        doc["differences"] = clean(differences(all_metrics))
    return json.dumps(doc, indent=2)


# --- plots ------------------------------------------------------------------------------------


def _plt():
    import matplotlib

    matplotlib.use("Agg")  # files only; never needs a display
    import matplotlib.pyplot as plt

    return plt


def is_rotor(flight: Flight) -> bool:
    """Rotor (gimballed top) flights get the z-axis track of reference 1, Figure 1."""
    return "rotor" in flight.meta.get("scene", "").lower() or "rotor" in flight.name.lower()


def write_plots(flights: list[Flight], outdir: str | Path, prefix: str = "flight") -> list[Path]:
    """Draw the standard figures for one flight, or overlays for several, to PNG files.

    Returns the paths written: ``<prefix>-altitude.png`` (altitude and climb rate with the
    demand), ``-attitude.png`` (ZXZ angles and body rates), ``-throttles.png``,
    ``-trajectory.png`` (3-D, world frame, relative to the start) and, for rotor flights,
    ``-ztrack.png`` (body z axis in world coordinates, reference 1 Figure 1).
    """
    plt = _plt()
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    label = len(flights) > 1

    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for f in flights:
        a1.plot(f.t, f.altitude, label=f"{f.name} altitude" if label else "altitude")
        if len(f.demand):
            td = np.concatenate([f.demand_t, [f.t[-1]]])
            a1.step(td, np.concatenate([f.demand, [f.demand[-1]]]), where="post", ls="--",
                    label=f"{f.name} demand" if label else "demand")
        a2.plot(f.t, f.climb_rate, label=f.name if label else None)
    a1.set_ylabel("altitude [m]")
    a1.legend(loc="best", fontsize="small")
    a2.set_ylabel("climb rate [m/s]")
    a2.set_xlabel("simulation time [s]")
    if label:
        a2.legend(loc="best", fontsize="small")
    a1.grid(True)
    a2.grid(True)
    paths.append(_save(fig, out / f"{prefix}-altitude.png", plt))

    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for f in flights:
        for i, nm in enumerate(("phi", "theta", "psi")):
            a1.plot(f.t, np.degrees(f.euler[:, i]), label=f"{f.name} {nm}" if label else nm)
        for i, nm in enumerate(("x", "y", "z")):
            a2.plot(f.t, f.omega_B[:, i], label=f"{f.name} omega_{nm}" if label else f"omega_{nm}")
    a1.set_ylabel("ZXZ Euler angles [deg]")
    a2.set_ylabel("body rates [rad/s]")
    a2.set_xlabel("simulation time [s]")
    for a in (a1, a2):
        a.grid(True)
        a.legend(loc="best", fontsize="small", ncol=3)
    paths.append(_save(fig, out / f"{prefix}-attitude.png", plt))

    fig, ax = plt.subplots(figsize=(8, 4))
    for f in flights:
        for i in range(f.throttles.shape[1] if f.throttles.ndim == 2 else 0):
            ax.plot(f.t, f.throttles[:, i], label=f"{f.name} thruster {i}" if label else f"thruster {i}")
    ax.set_ylabel("throttle [0-1]")
    ax.set_xlabel("simulation time [s]")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(True)
    ax.legend(loc="best", fontsize="small")
    paths.append(_save(fig, out / f"{prefix}-throttles.png", plt))

    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    for f in flights:
        d = f.r_W - f.r_W[0]
        ax.plot(d[:, 0], d[:, 1], d[:, 2], label=f.name)
    ax.set_xlabel("x_W - x0 [m]")
    ax.set_ylabel("y_W - y0 [m]")
    ax.set_zlabel("z_W - z0 [m]")
    ax.legend(loc="best", fontsize="small")
    paths.append(_save(fig, out / f"{prefix}-trajectory.png", plt))

    if any(is_rotor(f) for f in flights):
        fig = plt.figure(figsize=(6, 6))
        ax = fig.add_subplot(projection="3d")
        for f in flights:
            if is_rotor(f):
                z = f.z_axis_track()
                ax.plot(z[::2, 0], z[::2, 1], z[::2, 2], label=f.name)
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1, 1)
        ax.set_zlim(-1, 1)
        ax.set_title("z-axis track (body z in world coordinates)")
        paths.append(_save(fig, out / f"{prefix}-ztrack.png", plt))
    return paths


def _save(fig: Any, path: Path, plt: Any) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
