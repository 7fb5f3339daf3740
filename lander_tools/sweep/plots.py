"""Sweep plots (PNG, matplotlib Agg): metric histograms, metric vs dispersed parameter, worst flights.

Each kind has a ``*_figure`` builder (returns the matplotlib Figure; labels with units, one colour
per controller or flight, key outside the axes, see :mod:`lander_tools.plotstyle`) and a writer.

The worst flights are re-flown alone with trajectory recording: a flight is a function of
``(master seed, index)``, so the replay is the flight of the table, not a look-alike.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lander_tools import plotstyle as ps
from lander_tools.sweep.dispersion import PARAMETER_COLUMNS
from lander_tools.sweep.spec import SweepSpec, metric_label

#: Metrics shown against the dispersed parameters (the ones a reader asks about first).
SCATTER_METRICS = ("hover_error", "settling_time", "max_tilt", "hover_time", "fuel_left", "powered_fuel")


#: Units of the dispersed parameters (:meth:`FlightCase.parameters`) on the plots' x axes.
PARAMETER_UNITS: dict[str, str] = {
    "tilt": "rad", "body_rate": "rad/s", "altitude_offset": "m", "velocity_offset": "m/s",
    "wind_mean": "m/s", "wind_gust": "m/s", "demand_step": "m", "mass_error": "relative, -",
    "inertia_error": "relative, -", "thrust_error_max": "relative, -", "failed_thruster": "index",
    "failure_time": "s", "orbit_altitude": "m", "orbit_phase": "rad", "density_error": "relative, -",
    "thruster_cant_max": "rad", "sensor_noise_error": "relative, -", "sensor_bias_error": "relative, -",
}


def parameter_label(param: str) -> str:
    return f"{param} [{PARAMETER_UNITS.get(param, '-')}]"


def _values(rows: Sequence[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([float(r.get(key, math.nan)) for r in rows], dtype=float)


def histograms_figure(rows: Sequence[dict[str, Any]], metrics: Sequence[str]) -> Any:
    """One histogram per metric; one colour per controller in every panel, the key above."""
    plt = ps.pyplot()
    labels = list(dict.fromkeys(r["controller"] for r in rows))
    n = len(metrics)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow + 0.4), squeeze=False, layout="constrained")
    for ax, m in zip(axes.flat, metrics):
        drawn = False
        for i, lab in enumerate(labels):
            v = _values([r for r in rows if r["controller"] == lab], m)
            v = v[np.isfinite(v)]
            if v.size:
                ax.hist(v, bins=30, alpha=0.6, color=ps.colour(i))
                drawn = True
        if not drawn:  # e.g. touchdown figures of a hover sweep: say so rather than show empty axes
            ax.text(0.5, 0.5, "no finite value\n(NaN in every flight)", transform=ax.transAxes, ha="center", va="center")
        ax.set_xlabel(metric_label(m))
        ax.set_ylabel("flights")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    counts = [sum(1 for r in rows if r["controller"] == lab) for lab in labels]
    ps.legend_outside(fig, ps.colour_key(labels), [f"{lab} (n={c})" for lab, c in zip(labels, counts)])
    return fig


def histograms(rows: Sequence[dict[str, Any]], metrics: Sequence[str], path: Path) -> Path:
    return ps.save(histograms_figure(rows, metrics), path, dpi=90)


def active_parameters(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Dispersed parameters that actually vary in this sweep."""
    out = []
    for p in PARAMETER_COLUMNS:
        v = _values(rows, p)
        v = v[np.isfinite(v)]
        if v.size and np.ptp(v) > 0.0:
            out.append(p)
    return out


def scatter_figure(rows: Sequence[dict[str, Any]], metrics: Sequence[str]) -> Any | None:
    """Grid: each kept scatter metric (rows) against each varying parameter (columns); failures in red."""
    params = active_parameters(rows)
    # A metric NaN in every flight (e.g. hover_time when no hover was held) gets no empty row.
    ms = [m for m in SCATTER_METRICS if m in metrics and bool(np.isfinite(_values(rows, m)).any())]
    if not params or not ms:
        return None
    plt = ps.pyplot()
    ok = np.array([bool(r["success"]) for r in rows])
    fig, axes = plt.subplots(len(ms), len(params), figsize=(3.0 * len(params), 2.6 * len(ms) + 0.4),
                             squeeze=False, layout="constrained")
    for i, m in enumerate(ms):
        y = _values(rows, m)
        for j, p in enumerate(params):
            x = _values(rows, p)
            ax = axes[i, j]
            ax.scatter(x[ok], y[ok], s=4, alpha=0.5, color="C0")
            ax.scatter(x[~ok], y[~ok], s=8, color="red", alpha=0.8)
            ax.set_xlabel(parameter_label(p))
            ax.set_ylabel(metric_label(m))
    from matplotlib.lines import Line2D

    key = [Line2D([], [], ls="", marker="o", color="C0"), Line2D([], [], ls="", marker="o", color="red")]
    ps.legend_outside(fig, key, ["success", "failure"])
    return fig


def scatter(rows: Sequence[dict[str, Any]], metrics: Sequence[str], path: Path) -> Path | None:
    fig = scatter_figure(rows, metrics)
    return None if fig is None else ps.save(fig, path, dpi=80)


def worst(rows: Sequence[dict[str, Any]], n: int) -> list[dict[str, Any]]:
    """Failures first, then the largest hover error."""
    def key(r: dict[str, Any]) -> tuple[int, float]:
        h = r.get("hover_error", math.nan)
        return (int(bool(r["success"])), -(h if isinstance(h, float) and math.isfinite(h) else math.inf))

    return sorted(rows, key=key)[:n]


def worst_trajectories_figure(spec: SweepSpec, rows: Sequence[dict[str, Any]], n: int = 4) -> Any | None:
    """The ``n`` worst flights re-flown: altitude (dashed: demand), tilt, mean throttle; one colour a flight."""
    from lander_tools.sweep.flight import fly_case

    picks = worst([r for r in rows if r["outcome"] != "error"], n)  # a flight that raised has no trajectory
    if not picks:
        return None
    plt = ps.pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(8, 8.5), sharex=True, layout="constrained")
    names = []
    for i, r in enumerate(picks):
        tr = fly_case(spec, r["controller_index"], r["index"], record=True).trajectory
        assert tr is not None  # record=True always returns one
        names.append(f"#{r['index']} {r['controller']} ({r['outcome']})")
        c, gid = ps.colour(i), names[-1]
        axes[0].plot(tr.t, tr.altitude, color=c, gid=gid)
        axes[0].plot(tr.t, tr.demand, ls="--", color=c, lw=0.8, gid=gid)
        axes[1].plot(tr.t, np.degrees(tr.tilt), color=c, gid=gid)
        axes[2].plot(tr.t, tr.throttles.mean(axis=1), color=c, gid=gid)
    axes[0].set_ylabel("altitude [m]")
    axes[1].set_ylabel("tilt from vertical [deg]")
    axes[2].set_ylabel("mean throttle [0-1]")
    for ax in axes:
        ax.set_xlabel("simulation time [s]")
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.grid(True)
    handles = ps.colour_key(names) + ps.style_key(["-", "--"], ["altitude", "demand altitude"])
    ps.legend_outside(fig, handles, [h.get_label() for h in handles])
    return fig


def worst_trajectories(spec: SweepSpec, rows: Sequence[dict[str, Any]], path: Path, n: int = 4) -> Path | None:
    fig = worst_trajectories_figure(spec, rows, n)
    return None if fig is None else ps.save(fig, path, dpi=80)


def all_plots(spec: SweepSpec, rows: Sequence[dict[str, Any]], out: Path, n_worst: int = 4) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    made = [histograms(rows, spec.metrics, out / "histograms.png")]
    for p in (scatter(rows, spec.metrics, out / "scatter.png"), worst_trajectories(spec, rows, out / "worst.png", n_worst)):
        if p is not None:
            made.append(p)
    return made
