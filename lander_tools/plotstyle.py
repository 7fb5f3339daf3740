"""What every figure the project draws shares (matplotlib, Agg): one colour per flight, legends
outside the data, equal scales in 3-D, and a check that every axis is labelled.

Used by :mod:`lander_tools.analysis`, :mod:`lander_tools.sweep.plots` and the benchmarks in
``bench/``. Figures use the constrained layout, so a legend placed with :func:`legend_outside`
gets room of its own beside or above the axes instead of covering lines.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: Line styles that tell apart the components of one flight (Euler angles, thrusters) when the
#: colour is the flight's.
LINESTYLES = ("-", "--", ":", "-.")

#: Shrinks a 3-D box inside its axes so the z label is not cut at the figure's edge (the
#: constrained layout does not see 3-D axis labels).
BOX_ZOOM_3D = 0.85


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (files only, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def colour(i: int) -> str:
    """Colour of flight (or controller) number ``i``: the same in every panel of a figure."""
    return f"C{i % 10}"


def legend_outside(fig: Any, handles: Sequence[Any], labels: Sequence[str], title: str | None = None,
                   where: str = "outside upper center") -> Any:
    """A figure legend outside the axes (constrained layout makes room); none when empty.

    An empty legend is skipped rather than drawn, which also avoids matplotlib's
    "No artists with labels found to put in legend" warning.
    """
    if not handles:
        return None
    ncols = min(len(handles), 4) if "upper center" in where or "lower center" in where else 1
    return fig.legend(handles, labels, loc=where, ncols=ncols, fontsize="small", title=title)


def style_key(styles: Sequence[str], names: Sequence[str], colour_: str = "0.3") -> list[Any]:
    """Legend handles that explain line styles (grey lines in each style)."""
    from matplotlib.lines import Line2D

    return [Line2D([], [], color=colour_, ls=ls, label=n) for ls, n in zip(styles, names)]


def colour_key(names: Sequence[str], colours: Sequence[str] | None = None) -> list[Any]:
    """Legend handles for flights (or controllers): one solid line in each one's colour
    (``colour(i)`` for the i-th name unless ``colours`` are given)."""
    from matplotlib.lines import Line2D

    cs = list(colours) if colours is not None else [colour(i) for i in range(len(names))]
    return [Line2D([], [], color=c, label=n) for c, n in zip(cs, names)]


def equal_limits_3d(ax: Any, points: Sequence[np.ndarray], margin: float = 0.05) -> None:
    """Give a 3-D axes one scale on x, y and z: a cube around all ``points`` ((N, 3) arrays).

    Without this matplotlib fits each axis to its own data, so a flight that moves 100 m along
    y and 1e-2 m along z shows the z noise as large as the motion.
    """
    pts = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 3) for p in points])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if not len(pts):
        return
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) * (1.0 + margin)
    half = half if half > 0.0 else 1.0  # a single point: a 2 m cube around it
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=BOX_ZOOM_3D)


def unlabelled_axes(fig: Any) -> list[str]:
    """Axes of ``fig`` with an axis that has no label text: ``["<title> x", ...]`` (empty: all labelled).

    Colour bars count as axes too (their one axis is checked). 3-D axes are checked on x, y and z.
    """
    missing = []
    for k, ax in enumerate(fig.get_axes()):
        if not _shows_axes(ax):
            continue
        name = ax.get_title() or ax.get_label() or f"axes {k}"
        if ax.get_label() == "<colorbar>":  # one axis: the bar's own
            if not (ax.get_ylabel() or ax.get_xlabel()).strip():
                missing.append(f"{name} colour bar")
            continue
        axes = [("x", ax.get_xlabel()), ("y", ax.get_ylabel())]
        if hasattr(ax, "get_zlabel"):
            axes.append(("z", ax.get_zlabel()))
        missing += [f"{name} {a}" for a, text in axes if not text.strip()]
    return missing


def _shows_axes(ax: Any) -> bool:
    """Visible and with its axes on (3-D axes keep ``axison`` False: they draw their own)."""
    return bool(ax.get_visible() and (ax.axison or ax.name == "3d"))


def save(fig: Any, path: Path, dpi: int = 100) -> Path:
    """Write ``fig`` to ``path`` (PNG) and close it."""
    plt = pyplot()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
