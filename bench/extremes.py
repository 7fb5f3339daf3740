"""Stability at the extremes: where each method stays bounded and where it blows up.

Four sweeps: step size x spin rate on the torque-free asymmetric top (up to hundreds of rad/s,
as after burning all fuel in scenario 8); the seed's close encounter with gimbal lock in Euler
angles vs quaternions; elongated and near-degenerate inertia; throttle bang-bang.

    python bench/extremes.py [--json FILE] [--out DIR] [--quick]
"""
from __future__ import annotations

import math
import sys

import _common as C
import numpy as np

from lander_sim.integrators import make
from lander_sim.integrators.reference import quat_distance
from lander_sim.physics import rotation
from lander_sim.physics.rigid_body import kinetic_energy
from lander_sim.physics.state import pack

METHODS = ("symplectic-euler", "verlet", "geometric", "rk4")


def _classify(err: float) -> str:
    if not math.isfinite(err) or err >= 1.0:
        return "BLOW"
    return "ok" if err < 1e-3 else "drift"


def _energy_run(name: str, inertia, omega0, dt: float, n: int) -> float:
    """max relative rotational-energy error over n steps (inf if it overflowed)."""
    dyn = C.free_top(tuple(inertia))
    y = pack(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.asarray(omega0, float), 0.0)
    e0 = kinetic_energy(*inertia, y[10:13])
    integ = make(name)
    worst = 0.0
    with np.errstate(all="ignore"):
        for i in range(n):
            try:
                integ.step(dyn, i * dt, y, dt)
            except (OverflowError, FloatingPointError, ValueError, ZeroDivisionError):
                return math.inf
            if i % 10 == 9:
                e = kinetic_energy(*inertia, y[10:13])
                err = abs(e / e0 - 1.0) if math.isfinite(e) else math.inf
                if not err < 1e6:
                    return math.inf
                worst = max(worst, err)
    return worst


def spin_sweep(quick: bool) -> list[dict]:
    inertia = (1.0, 2.0, 3.0)
    spins = [1.0, 10.0, 100.0, 300.0] if not quick else [1.0, 100.0, 300.0]
    dts = [0.1, 0.01, 0.001] if not quick else [0.1, 0.01]
    n = 300 if quick else 1000
    rows = []
    for name in METHODS:
        for w in spins:
            for dt in dts:
                # Near the intermediate axis, the Dzhanibekov state scaled to |w|.
                err = _energy_run(name, inertia, np.array([0.005, 1.0, 0.005]) * w, dt, n)
                rows.append(dict(method=name, spin=w, dt=dt, w_dt=w * dt, steps=n, energy_error=err, status=_classify(err)))
    return rows


def gimbal_lock(quick: bool) -> list[dict]:
    """Seed 1 task 2 close encounter: E = (0, pi/2, 0), w = (0, 1, 0) under the rotor's weight."""
    T = 5.0
    rows = []
    dq, yq = C.scene_dynamics("gimbal-lock-close-quaternion")
    ref = yq.copy()
    make("adaptive", rtol=1e-12, atol=1e-12).step(dq, 0.0, ref, T)
    for mode, scene in (("euler", "gimbal-lock-close"), ("quaternion", "gimbal-lock-close-quaternion")):
        dyn, y0 = C.scene_dynamics(scene)
        for name in ("symplectic-euler", "verlet", "rk4", "adaptive") + (("geometric",) if mode == "quaternion" else ()):
            for dt in ([0.01] if quick else [0.01, 0.001]):
                integ = make(name, rtol=1e-8, atol=1e-8) if name == "adaptive" else make(name)
                n = round(T / dt)
                with np.errstate(all="ignore"):
                    y, _, _ = C.run_fixed(integ, dyn, y0, dt, n)
                q = y[6:10] if mode == "quaternion" else rotation.euler_to_quat(y[6:9])
                err = quat_distance(q, ref[6:10]) if np.all(np.isfinite(q)) else math.inf
                rows.append(dict(attitude=mode, method=name, dt=dt, attitude_error=err, status=_classify(err)))
    return rows


def inertia_extremes(quick: bool) -> list[dict]:
    cases = {"rod (0.01,1,1)": (0.01, 1.0, 1.0), "near-symmetric (1,1,1+1e-9)": (1.0, 1.0, 1.0 + 1e-9), "flat (1,1,2)": (1.0, 1.0, 2.0)}
    rows = []
    for label, inertia in cases.items():
        for name in METHODS:
            for dt in ([0.01] if quick else [0.01, 0.001]):
                err = _energy_run(name, inertia, np.array([1.0, 0.7, 0.5]), dt, 300 if quick else 1000)
                rows.append(dict(inertia=label, method=name, dt=dt, energy_error=err, status=_classify(err)))
    return rows


def bang_bang(quick: bool) -> list[dict]:
    """Hover lander, thruster 1 switched 0 <-> 1 every 0.2 s (others 0.5): error vs the adaptive reference."""
    T = 4.0 if quick else 10.0
    rows = []

    def flight(name: str, dt: float, **opts) -> np.ndarray:
        dyn, y = C.scene_dynamics("hover", throttles=[0.5, 0.5, 0.5, 0.5])
        integ = make(name, **opts)
        n = round(T / dt)
        per = round(0.2 / dt)
        for i in range(n):
            dyn.inputs.throttles[0] = 1.0 if (i // per) % 2 == 0 else 0.0
            integ.step(dyn, i * dt, y, dt)
        return y

    ref = flight("adaptive", 0.01, rtol=1e-12, atol=1e-12)
    for name in METHODS:
        for dt in ([0.1, 0.01] if quick else [0.2, 0.1, 0.05, 0.01]):
            y = flight(name, dt)
            rows.append(dict(method=name, dt=dt, position_error=float(np.linalg.norm(y[0:3] - ref[0:3])),
                             attitude_error=quat_distance(y[6:10], ref[6:10])))
    return rows


def plot(data: dict) -> object:
    """Stability maps (spin rate against step), one panel per method, coloured by the largest
    relative energy error and marked with the status (``data``: this benchmark's JSON)."""
    spin = data["spin_sweep"]
    dts = sorted({r["dt"] for r in spin}, reverse=True)
    spins = sorted({r["spin"] for r in spin})
    cell = {(r["method"], r["spin"], r["dt"]): r for r in spin}
    methods = [m for m in METHODS if any(r["method"] == m for r in spin)]
    plt = C.pyplot()
    fig, axes = plt.subplots(1, len(methods), figsize=(3.6 * len(methods), 3.4), sharey=True, squeeze=False,
                             layout="constrained")
    for ax, m in zip(axes[0], methods):
        grid = np.array([[min(cell[m, w, d]["energy_error"], 1e3) for d in dts] for w in spins])
        im = ax.imshow(np.log10(np.maximum(grid, 1e-16)), origin="lower", cmap="viridis", vmin=-16, vmax=3, aspect="auto")
        ax.set_xticks(range(len(dts)), [f"{d:g}" for d in dts])
        ax.set_yticks(range(len(spins)), [f"{w:g}" for w in spins])
        ax.set_title(m)
        ax.set_xlabel("step dt [s]")
        ax.set_ylabel("|omega| [rad/s]")
        ax.yaxis.set_tick_params(labelleft=True)
        for i, w in enumerate(spins):
            for j, d in enumerate(dts):
                ax.text(j, i, cell[m, w, d]["status"], ha="center", va="center", color="w", fontsize=8)
    fig.colorbar(im, ax=axes[0], label="log10 max relative energy error [-]")
    return fig


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    spin = spin_sweep(args.quick)
    dts = sorted({r["dt"] for r in spin}, reverse=True)
    spins = sorted({r["spin"] for r in spin})
    cell = {(r["method"], r["spin"], r["dt"]): r for r in spin}
    print(C.table(f"stability map: torque-free top I=(1,2,3) near its intermediate axis, {spin[0]['steps']} steps; "
                  "cell = status (max rel. energy error); ok < 1e-3 <= drift < 1 <= BLOW",
                  ["method", "|w| rad/s"] + [f"dt={d:g}" for d in dts],
                  [[m, w] + [f"{cell[m, w, d]['status']} ({cell[m, w, d]['energy_error']:.1e})" for d in dts] for m in METHODS for w in spins]))
    gl = gimbal_lock(args.quick)
    print(C.table("close encounter with gimbal lock (seed 1 task 2), attitude error after 5 s vs quaternion reference",
                  ["attitude", "method", "dt", "error", "status"], [[r["attitude"], r["method"], r["dt"], r["attitude_error"], r["status"]] for r in gl]))
    ie = inertia_extremes(args.quick)
    print(C.table("elongated / near-degenerate inertia, w0 = (1, 0.7, 0.5) rad/s: max rel. energy error",
                  ["inertia", "method", "dt", "energy err", "status"], [[r["inertia"], r["method"], r["dt"], r["energy_error"], r["status"]] for r in ie]))
    bb = bang_bang(args.quick)
    print(C.table("throttle bang-bang (hover, thruster 1 toggled every 0.2 s): error vs adaptive 1e-12",
                  ["method", "dt", "|dr| m", "|dq|"], [[r["method"], r["dt"], r["position_error"], r["attitude_error"]] for r in bb]))
    return C.write_outputs(args, {"spin_sweep": spin, "gimbal_lock": gl, "inertia": ie, "bang_bang": bb}, plot,
                           "bench-extremes.png")


if __name__ == "__main__":
    sys.exit(main())
