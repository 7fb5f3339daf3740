"""Work-precision of every integrator (and scipy's solve_ivp as the peer) on four problems.

Error against a closed form where one exists (Kepler orbit), otherwise against the adaptive
method at tolerance 1e-12; cost as derivative evaluations and wall time. A second table
measures the long-run energy and |L_W| drift of each method on the torque-free asymmetric top.

    python bench/integrators.py [--json FILE] [--out DIR] [--quick]
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np

import _common as C
from lander_sim.integrators import make
from lander_sim.integrators.health import HealthMonitor, angular_momentum_W
from lander_sim.integrators.reference import kepler_state, quat_distance
from lander_sim.physics import constants as const
from lander_sim.physics.rigid_body import kinetic_energy
from lander_sim.physics.state import pack


@dataclass
class Problem:
    name: str
    dyn: object
    y0: np.ndarray
    T: float
    dts: list[float]
    error: Callable[[np.ndarray], float]  # error of a final state
    unit: str
    publish: float  # output interval given to the adaptive method [s]


def _problems(quick: bool) -> list[Problem]:
    out: list[Problem] = []
    ref_cache: dict[str, np.ndarray] = {}

    def reference(key: str, dyn, y0, T) -> np.ndarray:
        if key not in ref_cache:
            integ = make("adaptive", rtol=1e-12, atol=1e-12)
            y = y0.copy()
            integ.step(dyn, 0.0, y, T)
            ref_cache[key] = y
        return ref_cache[key]

    def quat_err(key, dyn, y0, T):
        return lambda y: quat_distance(y[6:10], reference(key, dyn, y0, T)[6:10])

    def pos_err(key, dyn, y0, T):
        return lambda y: float(np.linalg.norm(y[0:3] - reference(key, dyn, y0, T)[0:3]))

    nd = 2 if quick else 4
    # 1. Dzhanibekov: spin about the intermediate axis flips over every few seconds.
    dyn = C.free_top((1.0, 2.0, 3.0))
    y0 = pack(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.01, 2.0, 0.01]), 0.0)
    T = 10.0 if quick else 20.0
    out.append(Problem("dzhanibekov", dyn, y0, T, [0.04, 0.02, 0.01, 0.005][:nd], quat_err("dz", dyn, y0, T), "|dq|", 0.1))
    # 2. Seed 1 gimballed rotor (weight on the spin axis, fixed pivot).
    dyn, y0 = C.scene_dynamics("rotor-quaternion")
    T = 5.0 if quick else 10.0
    out.append(Problem("rotor", dyn, y0, T, [0.02, 0.01, 0.005, 0.0025][:nd], quat_err("rotor", dyn, y0, T), "|dq|", 0.01))
    # 3. Kepler orbit round Mars, e = 0.3, a = 2 R: one period, closed form.
    gm, a, e = const.GM_MARS, 2.0 * const.MARS_RADIUS, 0.3
    period = 2.0 * math.pi * math.sqrt(a**3 / gm)
    dyn = C.point_orbit(gm)
    r0, v0 = kepler_state(0.0, gm, a, e)
    y0 = pack(r0, v0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.0)
    r_end, _ = kepler_state(period, gm, a, e)
    steps = [500, 1000, 2000, 4000][:nd]
    out.append(Problem("kepler", dyn, y0, period, [period / n for n in steps],
                       lambda y: float(np.linalg.norm(y[0:3] - r_end)), "|dr| m", period / 100))
    # 4. Lander descent from 10 km with drag, wind and (slightly unequal) thrust: 60 s.
    dyn, y0 = C.scene_dynamics("descent-10km", throttles=[0.40, 0.42, 0.40, 0.42], wind=[5.0, 0.0, 2.0])
    T = 30.0 if quick else 60.0
    out.append(Problem("descent", dyn, y0, T, [0.2, 0.1, 0.05, 0.025][:nd], pos_err("descent", dyn, y0, T), "|dr| m", 0.1))
    return out


def work_precision(quick: bool) -> list[dict]:
    rows: list[dict] = []
    tols = [1e-5, 1e-8] if quick else [1e-4, 1e-6, 1e-8, 1e-10]
    for p in _problems(quick):
        for name in C.FIXED:
            for dt in p.dts:
                n = round(p.T / dt)
                y, wall, ev = C.run_fixed(make(name), p.dyn, p.y0, p.T / n, n)
                rows.append(dict(problem=p.name, method=name, setting=f"dt={p.T / n:.4g}", error=p.error(y), unit=p.unit, evals=ev, wall=wall))
        for tol in tols:
            integ = make("adaptive", rtol=tol, atol=tol)
            n = round(p.T / p.publish)
            y, wall, ev = C.run_fixed(integ, p.dyn, p.y0, p.T / n, n)
            rows.append(dict(problem=p.name, method="adaptive", setting=f"tol={tol:g}", error=p.error(y), unit=p.unit, evals=ev, wall=wall,
                             accepted=integ.accepted, rejected=integ.rejected))
            for m in ("RK45", "DOP853"):
                y, wall, ev = C.run_scipy(m, p.dyn, p.y0, p.T, tol, tol)
                rows.append(dict(problem=p.name, method=f"scipy-{m}", setting=f"tol={tol:g}", error=p.error(y), unit=p.unit, evals=ev, wall=wall))
    return rows


def long_run_drift(quick: bool) -> list[dict]:
    """Energy and world angular momentum drift over n steps of the free asymmetric top."""
    n, dt = (10_000, 0.01) if quick else (100_000, 0.01)
    inertia = (1.0, 2.0, 3.0)
    rows = []
    for name, opts in [("verlet", {}), ("verlet", {"renormalise": False}), ("symplectic-euler", {}), ("rk4", {}), ("geometric", {}),
                       ("adaptive", {"rtol": 1e-8, "atol": 1e-8})]:
        dyn = C.free_top(inertia)
        y = pack(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.01, 2.0, 0.01]), 0.0)
        mon = HealthMonitor(energy=lambda y: kinetic_energy(*inertia, y[10:13]), angular_momentum_W=lambda y: angular_momentum_W(y, np.array(inertia)))
        integ = make(name, **opts)
        mon.observe(y)
        every = max(1, n // 1000)
        first = last = 0.0
        e0 = kinetic_energy(*inertia, y[10:13])
        for i in range(n):
            with np.errstate(all="ignore"):  # symplectic Euler overflows here: reported as inf
                integ.step(dyn, i * dt, y, dt)
            if (i + 1) % every == 0:
                mon.observe(y)
                err = abs(kinetic_energy(*inertia, y[10:13]) / e0 - 1.0)
                err = err if math.isfinite(err) else math.inf
                if i < n // 10:
                    first = max(first, err)
                elif i >= n - n // 10:
                    last = max(last, err)
        rep = mon.report(integ)
        label = name + ("" if "renormalise" not in opts else " (no renorm.)")
        rows.append(dict(method=label, steps=n, dt=dt, energy_drift=rep.energy_drift, first_tenth=first, last_tenth=last,
                         momentum_drift=rep.momentum_drift, quat_norm_error=rep.quat_norm_error))
    return rows


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    rows = work_precision(args.quick)
    for prob in dict.fromkeys(r["problem"] for r in rows):
        sub = [r for r in rows if r["problem"] == prob]
        print(C.table(f"work-precision: {prob} (error {sub[0]['unit']})", ["method", "setting", "error", "evals", "wall s", "acc/rej"],
                      [[r["method"], r["setting"], r["error"], r["evals"], r["wall"], f"{r['accepted']}/{r['rejected']}" if "accepted" in r else ""] for r in sub]))
    drift = long_run_drift(args.quick)
    print(C.table(f"long-run drift: torque-free asymmetric top I=(1,2,3), w0=(0.01,2,0.01) rad/s, {drift[0]['steps']} steps of {drift[0]['dt']} s",
                  ["method", "max dE/E", "first 10%", "last 10%", "max dL_W/L", "max | |q|-1 |"],
                  [[r["method"], r["energy_drift"], r["first_tenth"], r["last_tenth"], r["momentum_drift"], r["quat_norm_error"]] for r in drift]))
    C.write_json(args.json, {"work_precision": rows, "long_run_drift": drift})
    if args.out:
        plt = C.pyplot()
        probs = list(dict.fromkeys(r["problem"] for r in rows))
        fig, axes = plt.subplots(1, len(probs), figsize=(4.2 * len(probs), 3.8))
        for ax, prob in zip(axes, probs):
            sub = [r for r in rows if r["problem"] == prob]
            for m in dict.fromkeys(r["method"] for r in sub):
                pts = sorted((r["evals"], max(r["error"], 1e-17)) for r in sub if r["method"] == m)
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", label=m, ms=3)
            ax.set_title(prob)
            ax.set_xlabel("derivative evaluations")
            ax.set_ylabel(f"error ({sub[0]['unit']})")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        C.Path(args.out).mkdir(parents=True, exist_ok=True)
        fig.savefig(C.Path(args.out) / "bench-integrators.png", dpi=90)
    return 0


if __name__ == "__main__":
    sys.exit(main())
