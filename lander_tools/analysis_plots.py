"""The standard figures of recorded flights (``lander analyse --out``), chosen from what each
flight's scene has (:mod:`lander_tools.metrics_fit`).

``altitude`` (altitude with the demand in force, dashed, and climb rate), ``attitude`` (ZXZ Euler
angles and body rates), ``throttles``, ``trajectory`` (3-D, world frame) and, for a fixed pivot,
``ztrack`` (the body z axis in world coordinates, reference 1 Figure 1).

Euler angles are drawn in their ranges, ``phi, psi`` in (-180, 180] deg and ``theta`` in [0, 180]
deg, as :func:`canonical_zxz` maps them: an Euler-mode flight that passes near gimbal lock
(``sin theta = 0``, where eq 5's ``1/sin theta`` makes ``phi`` and ``psi`` race) integrates angles
that grow without bound (10^11 deg in seed 1's pendulum), and only their values modulo a turn
are an attitude. The spans the simulator flagged near lock are shaded on the angle panel.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from lander_tools import plotstyle as ps
from lander_tools.analysis import Flight


def _wrap(a: np.ndarray) -> np.ndarray:
    """Angles [rad] to (-pi, pi] (``np.mod`` by ``2 pi`` is exact in floating point)."""
    r = np.mod(a, 2.0 * np.pi)
    return np.where(r > np.pi, r - 2.0 * np.pi, r)


def canonical_zxz(E: np.ndarray) -> np.ndarray:
    """ZXZ angles ``(phi, theta, psi)`` [rad], shape (N, 3), mapped to ``theta`` in [0, pi] and
    ``phi, psi`` in (-pi, pi], the same rotation: ``R_z(phi) R_x(theta) R_z(psi)`` equals
    ``R_z(phi + pi) R_x(-theta) R_z(psi + pi)`` (eq 3), so a negative ``theta`` is flipped with
    half a turn on the other two. Non-finite angles stay NaN (no line is drawn there)."""
    E = np.array(E, dtype=float, ndmin=2)
    phi, theta, psi = _wrap(E[:, 0]), _wrap(E[:, 1]), _wrap(E[:, 2])
    flip = theta < 0.0
    theta = np.where(flip, -theta, theta)
    phi = np.where(flip, _wrap(phi + np.pi), phi)
    psi = np.where(flip, _wrap(psi + np.pi), psi)
    return np.column_stack([phi, theta, psi])


def _spans(t: np.ndarray, flag: np.ndarray) -> list[tuple[float, float]]:
    """``(start, end)`` times of the runs where ``flag`` is set (a one-state run spans that state
    to the next)."""
    f = np.asarray(flag, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], f.astype(int), [0]))))
    return [(float(t[a]), float(t[min(b, len(t) - 1)])) for a, b in zip(edges[::2], edges[1::2])]


def is_fixed_pivot(flight: Flight) -> bool:
    """A fixed pivot (the gimballed rotor's mount): by the scene's ``fixed_pivot``; for a bag whose
    scene is unknown, a body whose position never changed by a bit over the flight."""
    facts = flight.facts
    if facts is not None:
        return facts.fixed_pivot
    return bool(len(flight.t) > 1) and not np.any(flight.r_W - flight.r_W[0])



def over_surface(flight: Flight) -> bool:
    """Altitude and climb rate are figures of this flight: its scene has a surface to fly over
    (:attr:`~lander_tools.metrics_fit.SceneFacts.surface`); for a bag whose scene is unknown,
    anything but a fixed pivot."""
    facts = flight.facts
    return facts.surface if facts is not None else not is_fixed_pivot(flight)


#: Plot kinds :func:`figures` draws (``altitude`` only over a surface, ``ztrack`` only for a fixed pivot).
PLOT_KINDS = ("altitude", "attitude", "throttles", "trajectory", "ztrack")
_TIME = "simulation time [s]"


def _panels(plt: Any, n: int, height: float) -> tuple[Any, list[Any]]:
    """``n`` stacked panels on one time axis, each with its own time labels (a reader may look at
    any panel alone)."""
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(8, height), layout="constrained", squeeze=False)
    for ax in axes[:, 0]:
        ax.set_xlabel(_TIME)
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.grid(True)
    return fig, list(axes[:, 0])


def _components(fig: Any, flights: list[Flight], panels: list[tuple[Any, Any, list[str]]]) -> None:
    """Plot per-component series: ``panels`` is ``(axes, f -> (N, k) array, component names)``.

    One flight: a colour per component and a legend per panel. Several: the flight's colour
    (the same in every panel) and a line style per component, with a flight key above.
    """
    several = len(flights) > 1
    for ax, series, names in panels:
        for i, f in enumerate(flights):
            y = series(f)
            for j in range(y.shape[1] if y.ndim == 2 else 0):
                if several:
                    ax.plot(f.t, y[:, j], color=ps.colour(i), ls=ps.LINESTYLES[j % len(ps.LINESTYLES)], gid=f.name)
                else:
                    ax.plot(f.t, y[:, j], color=ps.colour(j), label=names[j] if j < len(names) else f"{j}", gid=f.name)
        k = min(len(names), len(ps.LINESTYLES))
        if several and k:
            ax.legend(handles=ps.style_key(ps.LINESTYLES[:k], names[:k]), loc="upper left",
                      bbox_to_anchor=(1.01, 1.0), fontsize="small")
        elif not several and ax.get_legend_handles_labels()[0]:  # none for a flight without thrusters
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    if several:
        ps.legend_outside(fig, ps.colour_key([f.name for f in flights]), [f.name for f in flights])


def figures(flights: list[Flight]) -> dict[str, Any]:
    """The standard figures of one flight, or of several overlaid, as matplotlib Figures by kind.

    ``altitude`` (altitude with the demand in force, dashed, and climb rate), ``attitude`` (ZXZ
    angles and body rates), ``throttles``, ``trajectory`` (3-D, world frame, relative to the
    start, one scale on every axis) and, for a fixed pivot, ``ztrack`` (body z axis in world
    coordinates, reference 1 Figure 1). A flight has one colour in every panel; legends sit
    outside the axes.
    """
    plt = ps.pyplot()
    names = [f.name for f in flights]
    out: dict[str, Any] = {}

    # Altitude and climb rate only for flights over a surface (metrics_fit): a fixed pivot or a
    # body in free space has neither.
    over = [i for i, f in enumerate(flights) if over_surface(f)]
    if over:
        fig, (a1, a2) = _panels(plt, 2, 6.5)
        for i in over:
            f, c = flights[i], ps.colour(i)
            a1.plot(f.t, f.altitude, color=c, gid=f.name)
            if len(f.demand):
                td = np.concatenate([f.demand_t, [f.t[-1]]]) if len(f.t) else f.demand_t
                hd = np.concatenate([f.demand, [f.demand[-1]]]) if len(f.t) else f.demand
                a1.step(td, hd, where="post", ls="--", color=c, lw=1.0, gid=f.name)
            a2.plot(f.t, f.climb_rate, color=c, gid=f.name)
        a1.set_ylabel("altitude [m]")
        a2.set_ylabel("climb rate [m/s]")
        key = ps.style_key(["-", "--"], ["altitude", "demand altitude"])
        handles = ps.colour_key([names[i] for i in over]) + key if len(flights) > 1 else key
        ps.legend_outside(fig, handles, [h.get_label() for h in handles])
        out["altitude"] = fig

    fig, (a1, a2) = _panels(plt, 2, 6.5)
    a1.set_ylabel("ZXZ Euler angle [deg]")
    a2.set_ylabel("body rate [rad/s]")
    # Shaded first, so that one flight's legend names it with the angles.
    spans = [s for f in flights for s in _spans(f.t, f.gimbal_lock)]
    for k, (t0, t1) in enumerate(spans):
        a1.axvspan(t0, t1, color="0.85", zorder=0, gid="near gimbal lock", label="near gimbal lock" if k == 0 else None)
    _components(fig, flights, [
        (a1, lambda f: np.degrees(canonical_zxz(f.euler)), ["phi", "theta", "psi"]),
        (a2, lambda f: f.omega_B, ["omega_x", "omega_y", "omega_z"]),
    ])
    if spans and len(flights) > 1:  # the panel's key holds line styles: add the shading to it
        from matplotlib.patches import Patch

        handles = list(a1.get_legend().legend_handles) + [Patch(color="0.85", label="near gimbal lock")]
        a1.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    a1.set_ylim(-190.0, 190.0)
    a1.set_yticks([-180, -90, 0, 90, 180])
    out["attitude"] = fig

    fig, (ax,) = _panels(plt, 1, 4.0)
    ax.set_ylabel("throttle [0-1]")
    ax.set_ylim(-0.05, 1.05)
    n_thr = max((f.throttles.shape[1] for f in flights if f.throttles.ndim == 2), default=0)
    _components(fig, flights, [(ax, lambda f: f.throttles, [f"thruster {j}" for j in range(n_thr)])])
    out["throttles"] = fig

    fig = plt.figure(figsize=(7, 6.5), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    tracks = []
    for i, f in enumerate(flights):
        d = f.r_W - f.r_W[0] if len(f.t) else f.r_W
        tracks.append(d)
        ax.plot(d[:, 0], d[:, 1], d[:, 2], color=ps.colour(i), gid=f.name)
    ps.equal_limits_3d(ax, tracks)
    ax.set_xlabel("x_W - x0 [m]")
    ax.set_ylabel("y_W - y0 [m]")
    ax.set_zlabel("z_W - z0 [m]", labelpad=8)
    ax.set_title("trajectory, world frame, from the start (one scale on every axis)")
    if len(flights) > 1:
        ps.legend_outside(fig, ps.colour_key(names), names)
    out["trajectory"] = fig

    rotors = [(i, f) for i, f in enumerate(flights) if is_fixed_pivot(f)]
    if rotors:
        out["ztrack"] = ztrack_figure([(f.name, f.z_axis_track(), ps.colour(i)) for i, f in rotors])
    return out


def ztrack_figure(tracks: list[tuple[str, np.ndarray, str]]) -> Any:
    """Reference 1 Figure 1: the body z axis in world coordinates, ``R(q)[2, :]`` (eq 13), as a
    3-D track on the unit sphere; ``tracks`` are ``(name, (N, 3) array, colour)``."""
    plt = ps.pyplot()
    fig = plt.figure(figsize=(6, 6.5), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    for name, z, c in tracks:
        ax.plot(z[::2, 0], z[::2, 1], z[::2, 2], color=c, gid=name)
    ax.set_xlim(-1, 1)
    ax.set_ylim(-1, 1)
    ax.set_zlim(-1, 1)
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=ps.BOX_ZOOM_3D)
    for axis, name in ((ax.xaxis, "x_W"), (ax.yaxis, "y_W"), (ax.zaxis, "z_W")):
        axis.set_ticks([-1.0, -0.5, 0.0, 0.5, 1.0])
        axis.set_label_text(f"{name} [-]")
    ax.set_title("body z axis in world coordinates (unit vector)")
    if len(tracks) > 1:
        ps.legend_outside(fig, ps.colour_key([n for n, _, _ in tracks], [c for _, _, c in tracks]),
                          [n for n, _, _ in tracks])
    return fig


def write_plots(flights: list[Flight], outdir: str | Path, prefix: str = "flight") -> list[Path]:
    """Draw :func:`figures` to ``<outdir>/<prefix>-<kind>.png`` and return the paths written."""
    out = Path(outdir)
    return [ps.save(fig, out / f"{prefix}-{kind}.png") for kind, fig in figures(flights).items()]
