"""Work-precision of every integrator (and scipy's solve_ivp as the peer) on four problems.

Error against a closed form where one exists (Kepler orbit), otherwise against the adaptive
method at tolerance 1e-12; cost as derivative evaluations and wall time. RK4, the adaptive
Dormand-Prince (local error control) and DOP853 run compiled (:mod:`lander_sim.fast.rk_kernels`)
wherever the model has a compiled form (all problems but the rotor), so the wall times compare
methods, not implementations; a fourth table holds our best compiled run against scipy's DOP853. A second table
measures the long-run energy and |L_W| drift of each method on the torque-free asymmetric top;
a third what it costs the adaptive method to meet a *global* tolerance on one Kepler orbit.

    python bench/integrators.py [--json FILE] [--out DIR] [--quick]
"""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import _common as C
import numpy as np

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
    problems = _problems(quick)
    _warm_up(problems)
    for p in problems:
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
            got = run_dop853(p.dyn, p.y0, p.T, tol)
            if got is not None:
                y, wall, ev = got
                rows.append(dict(problem=p.name, method="dop853", setting=f"tol={tol:g}", error=p.error(y), unit=p.unit, evals=ev, wall=wall))
    return rows


def _warm_up(problems: list[Problem]) -> None:
    """Compile (or load from numba's cache) the compiled methods before anything is timed."""
    for p in problems:
        if run_dop853(p.dyn, p.y0, p.T * 1e-3, 1e-3) is not None:
            y = p.y0.copy()
            for name in ("rk4", "adaptive", "geometric"):
                make(name).step(p.dyn, 0.0, y, p.T * 1e-3)
            make("adaptive", error_control="global").step(p.dyn, 0.0, y, p.T * 1e-3)
            return


def run_dop853(dyn, y0: np.ndarray, T: float, tol: float, repeats: int = 1) -> tuple[np.ndarray, float, int] | None:
    """The compiled DOP853 (:func:`lander_sim.fast.rk_kernels.dop853_span`) over [0, T] in one call:
    (final y, best wall time of ``repeats`` [s], evaluations); None if the model has no compiled form."""
    from lander_sim.fast.rk_kernels import compiled_model, dop853_span, dop853_tableau

    cm = compiled_model(dyn)
    if cm is None:
        return None
    thr, wind = cm.inputs()
    A, B, Cc, E3, E5 = dop853_tableau()
    best, y, stats = math.inf, y0.copy(), np.zeros(3)
    for _ in range(repeats):
        y, stats = y0.copy(), np.zeros(3)
        t0 = time.perf_counter()
        dop853_span(y, T, tol, tol, cm.params, cm.force, cm.torque, cm.burn, thr, wind, cm.translation, A, B, Cc, E3, E5, stats)
        best = min(best, time.perf_counter() - t0)
    return y, best, int(stats[2])


def compiled_kepler_rate(quick: bool, tol: float = 1e-10) -> float:
    """Derivative evaluations per second of the compiled DOP853 over one Kepler orbit (e = 0.3) at
    ``tol``, best of 3 (quick) or 7 calls after one untimed call: the regression guard's figure."""
    p = next(p for p in _problems(True) if p.name == "kepler")
    run_dop853(p.dyn, p.y0, p.T, tol)  # compile (or load) outside the timing
    got = run_dop853(p.dyn, p.y0, p.T, tol, repeats=3 if quick else 7)
    assert got is not None  # the orbit has a compiled form
    return got[2] / got[1]


def compiled_vs_scipy(quick: bool) -> list[dict]:
    """Our best compiled method against scipy's DOP853 on the Kepler orbit, the descent and the
    torque-free asymmetric top: for each tolerance, scipy's error and wall time, and the cheapest
    compiled run (DOP853 and adaptive Dormand-Prince, tolerances tol * 10^(-j/2), j = 0..4) whose
    error is at most scipy's; ``ratio`` = its wall time / scipy's (the acceptance: <= 0.1).
    Wall times are the best of 3 (the machine is shared)."""
    tols = [1e-4, 1e-7, 1e-10] if quick else [10.0**-k for k in range(4, 11)]
    probs = [p for p in _problems(quick) if p.name in ("kepler", "descent", "dzhanibekov")]
    rows: list[dict] = []
    for p in probs:
        run_dop853(p.dyn, p.y0, p.T, 1e-6)  # compile (or load) outside the timings
        for tol in tols:
            walls = []
            for _ in range(3):
                y, wall, ev = C.run_scipy("DOP853", p.dyn, p.y0, p.T, tol, tol)
                walls.append(wall)
            target = p.error(y)
            best: dict | None = None
            for method in ("dop853", "adaptive"):
                for j in range(5):
                    t2 = tol * 10.0 ** (-j / 2)
                    if t2 < 1e-14:
                        break
                    if method == "dop853":
                        got = run_dop853(p.dyn, p.y0, p.T, t2, repeats=3)
                        assert got is not None  # every problem here has a compiled form
                        y2, w2, e2 = got
                    else:
                        w2 = math.inf
                        for _ in range(3):
                            integ = make("adaptive", rtol=t2, atol=t2)
                            y2, w, e2 = C.run_fixed(integ, p.dyn, p.y0, p.T, 1)
                            w2 = min(w2, w)
                    err = p.error(y2)
                    if err <= target * (1.0 + 1e-9) or err <= 1e-15:
                        if best is None or w2 < best["wall"]:
                            best = dict(method=method, tol=t2, error=err, evals=e2, wall=w2)
                        break
            rows.append(dict(problem=p.name, tol=tol, scipy_error=target, scipy_evals=ev, scipy_wall=min(walls),
                             method=best["method"] if best else "-", method_tol=best["tol"] if best else math.nan,
                             error=best["error"] if best else math.nan, evals=best["evals"] if best else 0,
                             wall=best["wall"] if best else math.nan,
                             ratio=best["wall"] / min(walls) if best else math.nan))
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


def global_tolerance(quick: bool) -> list[dict]:
    """One Kepler orbit in one call: global error / tol of both error controls, and their cost.

    Units GM = a = 1 (period 2 pi), so one scalar ``rtol = atol = tol`` fits every component;
    the error is the global-mode tolerance's own norm, ``max_i |y_i - exact_i| / (tol + tol |y_i|)``
    over position and velocity. ``in 50 calls``: the global mode with the orbit cut into 50
    calls, each bounded on its own (the orbit's error is then not). ``cheapest local`` is the
    loosest local tolerance on the grid tol * 10^(-j/4) whose orbit meets ``tol``: found against
    the closed form, which a user does not have, so it is the least that meeting ``tol`` can
    cost with this pair.
    """
    tols = [1e-6, 1e-8] if quick else [1e-6, 1e-8, 1e-10]
    eccs = [0.3] if quick else [0.0, 0.3, 0.8]
    rows: list[dict] = []
    for e in eccs:
        r0, v0 = kepler_state(0.0, 1.0, 1.0, e)
        y0 = pack(r0, v0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.0)
        exact = np.concatenate(kepler_state(2.0 * math.pi, 1.0, 1.0, e))

        def run(tol: float, local: float, control: str, calls: int = 1,
                y0: np.ndarray = y0, exact: np.ndarray = exact) -> tuple[float, int, object]:
            """(error in tol's norm, evaluations, integrator): one orbit in ``calls`` calls at local tolerance ``local``."""
            integ = make("adaptive", rtol=local, atol=local, error_control=control)
            y, _, ev = C.run_fixed(integ, C.point_orbit(1.0), y0, 2.0 * math.pi / calls, calls)
            return float(np.max(np.abs(y[0:6] - exact) / (tol + tol * np.abs(y[0:6])))), ev, integ

        for tol in tols:
            loc, loc_ev, _ = run(tol, tol, "local")
            glob, glob_ev, g = run(tol, tol, "global")
            # The same orbit published 50 times: each call meets tol, the orbit need not.
            glob50, glob50_ev, _ = run(tol, tol, "global", calls=50)
            cheapest = (math.nan, 0)
            for j in range(17):
                tau = tol * 10.0 ** (-j / 4)
                if tau < 1e-14:  # the controller's round-off floor
                    break
                err, ev, _ = run(tol, tau, "local")
                if err <= 1.0:
                    cheapest = (tau, ev)
                    break
            rows.append(dict(ecc=e, tol=tol, local_error=loc, local_evals=loc_ev, global_error=glob, global_bound=g.global_error,
                             global_passes=g.passes, global_evals=glob_ev, global_50_calls_error=glob50, global_50_calls_evals=glob50_ev,
                             cheapest_local_tol=cheapest[0], cheapest_local_evals=cheapest[1]))
    return rows


def bound_margin(quick: bool) -> dict:
    """How far the global mode's reported bound is above the true error of the state it returns.

    Kepler orbits (GM = a = 1) over a grid of eccentricities, spans and tolerances, one call
    each; ratio = true error / bound in the tolerance's norm. The bound holds while the ratio
    is <= 1 (asymptotic theory: 1/31); the tolerance is met while the true error is <= 1.
    """
    eccs = [0.0, 0.3, 0.8] if quick else [0.0, 0.1, 0.3, 0.6, 0.8]
    spans = [1.0] if quick else [0.37, 1.0, 2.5]
    tols = [1e-5, 1e-7, 1e-9] if quick else [10.0**-k for k in range(4, 11)]
    ratios: list[float] = []
    worst_error = missed_bound = missed_tol = reported = 0.0
    for e in eccs:
        r0, v0 = kepler_state(0.0, 1.0, 1.0, e)
        y0 = pack(r0, v0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.0)
        for span in spans:
            T = span * 2.0 * math.pi
            exact = np.concatenate(kepler_state(T, 1.0, 1.0, e))
            for tol in tols:
                integ = make("adaptive", rtol=tol, atol=tol, error_control="global")
                y, _, _ = C.run_fixed(integ, C.point_orbit(1.0), y0, T, 1)
                err = float(np.max(np.abs(y[0:6] - exact) / (tol + tol * np.abs(y[0:6]))))
                ratios.append(err / integ.global_error)
                worst_error = max(worst_error, err)
                missed_bound += err > integ.global_error
                missed_tol += err > 1.0
                reported += integ.global_error > 1.0  # a miss the run itself reports
    return dict(runs=len(ratios), ratio_min=min(ratios), ratio_median=float(np.median(ratios)), ratio_max=max(ratios),
                worst_error=worst_error, bound_missed=int(missed_bound), tolerance_missed=int(missed_tol), reported_missed=int(reported),
                eccentricities=eccs, orbits=spans, tolerances=tols)


def plot(data: dict) -> object:
    """Work-precision diagrams, one column per problem, one colour per method in every panel; error
    against derivative evaluations (top) and against wall time (bottom: the compiled methods
    against scipy). ``data``: this benchmark's JSON; only ``work_precision`` is drawn."""
    from lander_tools import plotstyle as ps

    plt = C.pyplot()
    rows = data["work_precision"]
    probs = list(dict.fromkeys(r["problem"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    fig, axes = plt.subplots(2, len(probs), figsize=(4.2 * len(probs), 8.0), squeeze=False, layout="constrained")
    for row, (cost, label) in enumerate((("evals", "derivative evaluations [-]"), ("wall", "wall time [s]"))):
        for ax, prob in zip(axes[row], probs):
            sub = [r for r in rows if r["problem"] == prob]
            for i, m in enumerate(methods):
                pts = sorted((max(r[cost], 1e-7), max(r["error"], 1e-17)) for r in sub if r["method"] == m)
                if pts:
                    ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", color=ps.colour(i), ms=3)
            ax.set_title(prob)
            ax.set_xlabel(label)
            ax.set_ylabel(f"error [{sub[0]['unit']}]")
            ax.grid(True, which="both", alpha=0.3)
    ps.legend_outside(fig, ps.colour_key(methods), methods)
    return fig


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    rows = work_precision(args.quick)
    for prob in dict.fromkeys(r["problem"] for r in rows):
        sub = [r for r in rows if r["problem"] == prob]
        print(C.table(f"work-precision: {prob} (error {sub[0]['unit']})", ["method", "setting", "error", "evals", "wall s", "acc/rej"],
                      [[r["method"], r["setting"], r["error"], r["evals"], r["wall"], f"{r['accepted']}/{r['rejected']}" if "accepted" in r else ""] for r in sub]))
    cvs = compiled_vs_scipy(args.quick)
    print(C.table("compiled vs scipy DOP853: the cheapest compiled run reaching scipy's error (wall: best of 3)",
                  ["problem", "tol", "scipy error", "evals", "wall s", "ours", "at tol", "error", "evals", "wall s", "wall ratio"],
                  [[r["problem"], r["tol"], r["scipy_error"], r["scipy_evals"], r["scipy_wall"], r["method"], r["method_tol"],
                    r["error"], r["evals"], r["wall"], r["ratio"]] for r in cvs]))
    worst = max((r["ratio"] for r in cvs), default=math.nan)
    print(f"largest wall ratio ours / scipy DOP853: {worst:.3g} (acceptance: <= 0.1)\n")
    drift = long_run_drift(args.quick)
    print(C.table(f"long-run drift: torque-free asymmetric top I=(1,2,3), w0=(0.01,2,0.01) rad/s, {drift[0]['steps']} steps of {drift[0]['dt']} s",
                  ["method", "max dE/E", "first 10%", "last 10%", "max dL_W/L", "max | |q|-1 |"],
                  [[r["method"], r["energy_drift"], r["first_tenth"], r["last_tenth"], r["momentum_drift"], r["quat_norm_error"]] for r in drift]))
    glob = global_tolerance(args.quick)
    print(C.table("global tolerance: one Kepler orbit (GM = a = 1) in one call; error = max_i |dy_i| / (tol + tol |y_i|), r and v",
                  ["e", "tol", "local: error", "evals", "global: error", "bound", "passes", "evals", "in 50 calls: error", "evals",
                   "cheapest local tol", "evals"],
                  [[r["ecc"], r["tol"], r["local_error"], r["local_evals"], r["global_error"], r["global_bound"], r["global_passes"],
                    r["global_evals"], r["global_50_calls_error"], r["global_50_calls_evals"], r["cheapest_local_tol"], r["cheapest_local_evals"]]
                   for r in glob]))
    for e in dict.fromkeys(r["ecc"] for r in glob):
        sub = [r for r in glob if r["ecc"] == e]
        slope = np.polyfit(np.log10([r["tol"] for r in sub]), np.log10([r["local_error"] * r["tol"] for r in sub]), 1)[0]
        print(f"local mode, e = {e}: global error ~ tol^{slope:.2f}")
    margin = bound_margin(args.quick)
    print(f"\nglobal mode bound, {margin['runs']} orbits (e {margin['eccentricities']}, {margin['orbits']} periods, tol "
          f"{margin['tolerances'][0]:g}..{margin['tolerances'][-1]:g}): true error / bound min {margin['ratio_min']:.3g}, "
          f"median {margin['ratio_median']:.3g}, max {margin['ratio_max']:.3g}; largest true error / tol {margin['worst_error']:.3g}; "
          f"bound missed {margin['bound_missed']}, tolerance missed {margin['tolerance_missed']} "
          f"(reported as missed by the run: {margin['reported_missed']})\n")
    return C.write_outputs(args, {"work_precision": rows, "compiled_vs_scipy": cvs, "long_run_drift": drift, "global_tolerance": glob,
                                  "global_bound_margin": margin}, plot, "bench-integrators.png")


if __name__ == "__main__":
    sys.exit(main())
