"""Raw step speed of the core: velocity-Verlet steps per second of one lander (scenario 7's scene).

Four implementations of the same model, timed in the same run so their ratios are meaningful
on a noisy machine: the compiled kernel (lander_sim.fast), its ceiling (bench/ceiling.py: the
same physics fused, written only to be fast, alternating with the kernel), the numpy Dynamics
path (``VelocityVerlet(compiled=False)``, the reference), and a deliberately naive numpy
implementation (small arrays, np.cross and a rotation matrix per evaluation). Also reports numba's start-up cost (cold compile and cached
load, each in a fresh process) and checks the kernel against the numpy path.

    python bench/speed.py [--json FILE] [--out DIR] [--quick]
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
import time

import _common as C
import ceiling
import numpy as np

from lander_sim import fast
from lander_sim.integrators.verlet import VelocityVerlet
from lander_sim.physics import constants as const
from lander_sim.physics import rotation
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation

DT = 0.01
THROTTLES = [0.5, 0.48, 0.52, 0.5]
WIND = [3.0, 1.0, -2.0]
TARGET = 200_000


def hover_sim() -> Simulation:
    """The hover scene at ``DT`` with the bench's fixed throttles and wind."""
    sim = Simulation(load_scene("hover"), dt=DT)
    sim.set_throttles(THROTTLES)
    sim.set_wind(WIND)
    return sim


def naive_verlet(y0: np.ndarray, n: int) -> np.ndarray:
    """The same lander model written the obvious way: fresh small arrays everywhere."""
    veh = load_scene("hover").vehicle
    P = [np.array(t.position_B) for t in veh.thrusters]
    D = [np.array(t.direction_B) for t in veh.thrusters]
    th = np.array(THROTTLES)
    wind = np.array(WIND)
    k2 = np.array(veh.gyration_sq)

    def acc(y):
        r, v, q, w, fuel = y[0:3], y[3:6], y[6:10], y[10:13], y[13]
        m = veh.dry_mass + fuel
        I = np.diag(m * k2)
        F = -const.GM_MARS * m * r / np.linalg.norm(r) ** 3
        alt = np.linalg.norm(r) - const.MARS_RADIUS
        rho = const.ATMOSPHERE_SURFACE_DENSITY * math.exp(-alt / const.ATMOSPHERE_SCALE_HEIGHT) if alt < const.EXOSPHERE_ALTITUDE else 0.0
        W = wind - v
        F = F + 0.5 * rho * const.SPHERE_DRAG_COEFFICIENT * const.SPHERE_DRAG_AREA * np.linalg.norm(W) * W
        Fb = np.zeros(3)
        Q = np.zeros(3)
        if fuel > 0:
            for i in range(4):
                f = -D[i] * th[i] * const.LANDER_MAX_THRUST
                Fb = Fb + f
                Q = Q + np.cross(P[i], f)
        R = rotation.quat_to_matrix(q)
        a = (F + R.T @ Fb) / m
        wd = np.linalg.inv(I) @ (np.cross(I @ w, w) + Q)
        return a, wd

    y = y0.copy()
    for _ in range(n):
        a, wd = acc(y)
        fr = -0.5 * th.sum() if y[13] > 0 else 0.0
        wh = y[10:13] + 0.5 * DT * wd
        q = y[6:10] + rotation.quat_dot(y[6:10], wh) * DT
        y[6:10] = q / np.linalg.norm(q)
        vh = y[3:6] + 0.5 * DT * a
        y[0:3] = y[0:3] + vh * DT
        y[13] = max(0.0, y[13] + fr * DT)
        est = y.copy()
        est[10:13] = y[10:13] + DT * wd
        est[3:6] = y[3:6] + DT * a
        a1, wd1 = acc(est)
        y[10:13] = wh + 0.5 * DT * wd1
        y[3:6] = vh + 0.5 * DT * a1
    return y


def _startup(cache_dir: str) -> float:
    """Seconds for import + first kernel call in a fresh interpreter using ``cache_dir``."""
    code = (
        f"import time,sys; sys.path.insert(0, {str(C.ROOT)!r}); t=time.perf_counter();"
        "import numpy as np; from lander_sim.fast import lander_kernel as k;"
        "y=np.zeros(14); y[1]=-3.4e6; y[6]=1.0; y[13]=1.0; p=np.zeros(k.N_PARAMS); p[k.P_DRY]=1; p[k.P_K1]=p[k.P_K2]=p[k.P_K3]=1;"
        "k.verlet_steps(y, np.empty(14), 1, 0.01, p, np.zeros((1,3)), np.zeros((1,3)), np.zeros(1), np.zeros(1), np.zeros(3), 0.0);"
        "print(time.perf_counter()-t)"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def plot(res: dict) -> object:
    """Bar chart of the three implementations' steps per second (``res``: this benchmark's JSON)."""
    from lander_tools import plotstyle as ps

    plt = C.pyplot()
    fig, ax = plt.subplots(figsize=(7, 2.8), layout="constrained")
    labels = ["naive numpy", "numpy Dynamics", "compiled kernel"]
    vals = [res["naive_steps_per_s"], res["numpy_steps_per_s"], res["kernel_steps_per_s"]]
    ax.barh(labels, vals)
    line = ax.axvline(res.get("target_steps_per_s", TARGET), color="r", ls="--")
    ax.set_xscale("log")
    ax.set_xlabel("Verlet steps per second [1/s] (log scale)")
    ax.set_ylabel("implementation")
    ps.legend_outside(fig, [line], [f"target {res.get('target_steps_per_s', TARGET):,.0f} steps/s"])
    return fig


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    n_numpy = 2000 if args.quick else 20_000
    n_naive = 500 if args.quick else 5000
    chunks = 50 if args.quick else 500
    res: dict[str, float | int | bool | str] = {"numba": fast.HAVE_NUMBA, "dt": DT}

    with tempfile.TemporaryDirectory() as cache:
        res["startup_cold_s"] = _startup(cache)  # compiles and writes the cache
        res["startup_cached_s"] = _startup(cache)  # loads it

    sim = hover_sim()
    fl = fast.FastLander(sim.dynamics)
    y0 = sim.y.copy()
    yp = np.empty(14)
    # The numpy reference: the Simulation's integrator with its compiled step switched off.
    numpy_verlet = VelocityVerlet(renormalise=getattr(sim.integrator, "renormalise", True), compiled=False)
    # Kernel and ceiling (bench/ceiling.py: the same physics fused, written only to be fast),
    # alternating, chunks of 1000 steps (10 s of hover) from the same start so nothing stops early.
    side = ceiling.time_side_by_side(fl, y0, ceiling.constants(fl, np.asarray(THROTTLES), np.asarray(WIND)),
                                     chunks, 3 if args.quick else 5)
    res.update(side)
    # numpy Dynamics + Verlet path (what Simulation.step runs), same start.
    ref = y0.copy()
    t0 = time.perf_counter()
    for i in range(n_numpy):
        numpy_verlet.step(sim.dynamics, i * DT, ref, DT)
    res["numpy_steps_per_s"] = n_numpy / (time.perf_counter() - t0)
    # Naive implementation.
    t0 = time.perf_counter()
    yn = naive_verlet(y0, n_naive)
    res["naive_steps_per_s"] = n_naive / (time.perf_counter() - t0)
    # Agreement over 1000 steps (10 s, well before the tank runs dry): kernel vs numpy path
    # (same operation order), and naive vs numpy (same model, different operation order).
    n_cmp = 1000
    ref = y0.copy()
    for i in range(n_cmp):
        numpy_verlet.step(sim.dynamics, i * DT, ref, DT)
    yk = y0.copy()
    assert fl.advance(yk, yp, DT, n_cmp) == n_cmp
    scale = np.maximum(np.abs(ref), 1e-9)
    res["kernel_vs_numpy_max_rel"] = float(np.max(np.abs(yk - ref) / scale))
    res["ceiling_vs_kernel_max_rel"] = ceiling.agreement(fl, y0, ceiling.constants(fl, np.asarray(THROTTLES), np.asarray(WIND)), n_cmp)[0]
    n_naive = min(n_naive, n_cmp)
    yn = naive_verlet(y0, n_naive)
    ref_n = y0.copy()
    for i in range(n_naive):
        numpy_verlet.step(sim.dynamics, i * DT, ref_n, DT)
    res["naive_vs_numpy_max_rel"] = float(np.max(np.abs(yn - ref_n) / np.maximum(np.abs(ref_n), 1e-9)))
    res["kernel_over_numpy"] = res["kernel_steps_per_s"] / res["numpy_steps_per_s"]
    res["kernel_over_naive"] = res["kernel_steps_per_s"] / res["naive_steps_per_s"]
    res["numpy_over_naive"] = res["numpy_steps_per_s"] / res["naive_steps_per_s"]
    res["target_steps_per_s"] = TARGET
    res["target_met"] = res["kernel_steps_per_s"] >= TARGET

    print(C.table("velocity-Verlet steps per second, one lander (hover scene: gravity, sphere drag + wind, 4 thrusters, rotation), one core",
                  ["implementation", "steps/s", "x naive"],
                  [["compiled kernel (numba)" if fast.HAVE_NUMBA else "kernel (numba missing: plain Python)", f"{res['kernel_steps_per_s']:.0f}", res["kernel_over_naive"]],
                   ["ceiling: the same physics fused (bench/ceiling.py, not the product)", f"{res['ceiling_steps_per_s']:.0f}",
                    res["ceiling_steps_per_s"] / res["naive_steps_per_s"]],
                   ["numpy Dynamics path (Simulation)", f"{res['numpy_steps_per_s']:.0f}", res["numpy_over_naive"]],
                   ["naive numpy", f"{res['naive_steps_per_s']:.0f}", 1.0]]))
    print(C.table("start-up and agreement", ["figure", "value"], [
        ["numba cold start (import + compile), s", res["startup_cold_s"]],
        ["numba cached start (import + cache load), s", res["startup_cached_s"]],
        [f"kernel / ceiling (alternating, medians of {res['rounds']})", res["kernel_over_ceiling"]],
        [f"kernel vs numpy, max rel. difference after {n_cmp} steps", res["kernel_vs_numpy_max_rel"]],
        [f"ceiling vs kernel, max rel. difference after {n_cmp} steps", res["ceiling_vs_kernel_max_rel"]],
        [f"naive vs numpy, max rel. difference after {n_naive} steps", res["naive_vs_numpy_max_rel"]],
        [f"target {TARGET} steps/s met", str(res["target_met"])],
    ]))
    return C.write_outputs(args, res, plot, "bench-speed.png")


if __name__ == "__main__":
    sys.exit(main())
