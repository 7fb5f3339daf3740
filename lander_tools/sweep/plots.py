"""Sweep plots (PNG, matplotlib Agg): metric histograms, metric vs dispersed parameter, worst flights.

The worst flights are re-flown alone with trajectory recording: a flight is a function of
``(master seed, index)``, so the replay is the flight of the table, not a look-alike.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from lander_tools.sweep.dispersion import PARAMETER_COLUMNS
from lander_tools.sweep.spec import SweepSpec

#: Metrics shown against the dispersed parameters (the ones a reader asks about first).
SCATTER_METRICS = ("hover_error", "settling_time", "max_tilt")


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _values(rows: Sequence[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([float(r.get(key, math.nan)) for r in rows], dtype=float)


def histograms(rows: Sequence[dict[str, Any]], metrics: Sequence[str], path: Path) -> Path:
    plt = _plt()
    labels = list(dict.fromkeys(r["controller"] for r in rows))
    n = len(metrics)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
    for ax, m in zip(axes.flat, metrics):
        for lab in labels:
            v = _values([r for r in rows if r["controller"] == lab], m)
            v = v[np.isfinite(v)]
            if v.size:
                ax.hist(v, bins=30, alpha=0.6, label=f"{lab} (n={v.size})")
        ax.set_title(m)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def active_parameters(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Dispersed parameters that actually vary in this sweep."""
    out = []
    for p in PARAMETER_COLUMNS:
        v = _values(rows, p)
        v = v[np.isfinite(v)]
        if v.size and np.ptp(v) > 0.0:
            out.append(p)
    return out


def scatter(rows: Sequence[dict[str, Any]], metrics: Sequence[str], path: Path) -> Path | None:
    """Grid: each kept scatter metric (rows) against each varying parameter (columns); failures in red."""
    params = active_parameters(rows)
    ms = [m for m in SCATTER_METRICS if m in metrics]
    if not params or not ms:
        return None
    plt = _plt()
    ok = np.array([bool(r["success"]) for r in rows])
    fig, axes = plt.subplots(len(ms), len(params), figsize=(3.0 * len(params), 2.6 * len(ms)), squeeze=False)
    for i, m in enumerate(ms):
        y = _values(rows, m)
        for j, p in enumerate(params):
            x = _values(rows, p)
            ax = axes[i, j]
            ax.scatter(x[ok], y[ok], s=4, alpha=0.5, label="success")
            ax.scatter(x[~ok], y[~ok], s=8, c="red", alpha=0.8, label="failure")
            if i == len(ms) - 1:
                ax.set_xlabel(p)
            if j == 0:
                ax.set_ylabel(m)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def worst(rows: Sequence[dict[str, Any]], n: int) -> list[dict[str, Any]]:
    """Failures first, then the largest hover error."""
    def key(r: dict[str, Any]) -> tuple[int, float]:
        h = r.get("hover_error", math.nan)
        return (int(bool(r["success"])), -(h if isinstance(h, float) and math.isfinite(h) else math.inf))

    return sorted(rows, key=key)[:n]


def worst_trajectories(spec: SweepSpec, rows: Sequence[dict[str, Any]], path: Path, n: int = 4) -> Path | None:
    from lander_tools.sweep.flight import fly_case

    picks = [r for r in worst(rows, n) if r["outcome"] != "error"]
    if not picks:
        return None
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for r in picks:
        tr = fly_case(spec, r["controller_index"], r["index"], record=True).trajectory
        lab = f"#{r['index']} {r['controller']} ({r['outcome']})"
        line, = axes[0].plot(tr.t, tr.altitude, label=lab)
        axes[0].plot(tr.t, tr.demand, ls="--", color=line.get_color(), lw=0.8)
        axes[1].plot(tr.t, np.degrees(tr.tilt), color=line.get_color())
        axes[2].plot(tr.t, tr.throttles.mean(axis=1), color=line.get_color())
    axes[0].set_ylabel("altitude [m] (dashed: demand)")
    axes[1].set_ylabel("tilt from vertical [deg]")
    axes[2].set_ylabel("mean throttle [-]")
    axes[2].set_xlabel("t [s]")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def all_plots(spec: SweepSpec, rows: Sequence[dict[str, Any]], out: Path, n_worst: int = 4) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    made = [histograms(rows, spec.metrics, out / "histograms.png")]
    for p in (scatter(rows, spec.metrics, out / "scatter.png"), worst_trajectories(spec, rows, out / "worst.png", n_worst)):
        if p is not None:
            made.append(p)
    return made
