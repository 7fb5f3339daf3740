"""What this machine can do for the closed loop: one fused loop of bench/closed_loop.py's flight, beside the product's.

The product's compiled closed loop (:func:`lander_tools.sweep.batched_kernel.fly_flights`) flies
any flight of a sweep: thruster failures, Gauss-Markov gusts, a demand step, touchdown, fuel-out,
any law of :mod:`lander_autopilot.controllers.compiled`. :func:`loop_ceiling` is the one flight
bench/closed_loop.py times (``hover-canted`` with the ``combined`` law: altitude state feedback,
eq 18-19, plus ZXZ-angle attitude feedback, eq 28, summed with attitude priority; one Verlet step
per control period; no gusts, no failures) written only to be fast and used by nothing in the
product: every switch decided, the law's scalars and the state in local variables, the physics
step bench/ceiling.py's. Every expression keeps the product's operation order, so the samples
(altitude error, tilt, body rate) and the final state agree bit for bit, which :func:`agreement`
measures.

    python bench/ceiling_loop.py [--json FILE] [--quick]
"""
from __future__ import annotations

import math
import statistics
import sys
import time

import _common as C
import ceiling
import numpy as np

from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import HAVE_NUMBA, njit
from lander_sim.physics.constants import GM_MARS, MARS_RADIUS

# The fused loop calls bench/ceiling.py's compiled step: recompile when that file changes.
invalidate_if_changed(__file__, ceiling.__file__)

SCENE, LAW, DURATION = "hover-canted", "combined", 60.0
_TWO_PI = 2.0 * math.pi


@njit(cache=True, error_model="numpy")
def _wrap(a):  # pragma: no cover - compiled
    n = np.rint(a / _TWO_PI)
    return a - n * _TWO_PI


@njit(cache=True, error_model="numpy")
def loop_ceiling(y0, kc, force, torque, burn, law, K, dem, n_ctrl, dt, stop_radius, err, tilt, rate, y_out):  # pragma: no cover - compiled
    """The flight from ``y0``: samples into ``err``/``tilt``/``rate``, the last state into ``y_out``;
    returns (samples taken, saturated updates). ``kc``: bench/ceiling.py's constants (its thruster
    sums replaced here every period), ``law``: (dry, T_v, k_z, k_zd, design mass, mass scaled),
    ``dem``: (altitude, E_d (3), omega_d (3))."""
    n = force.shape[0]
    st = (y0[0], y0[1], y0[2], y0[3], y0[4], y0[5], y0[6], y0[7], y0[8], y0[9], y0[10], y0[11], y0[12], y0[13])
    l_dry, l_tv, k0, k1, l_mass, l_scaled = law[0], law[1], law[2], law[3], law[4], law[5] != 0.0
    d_alt, d_e0, d_e1, d_e2, d_w0, d_w1, d_w2 = dem[0], dem[1], dem[2], dem[3], dem[4], dem[5], dem[6]
    stop2 = stop_radius * stop_radius
    u = np.empty(n)
    sats = 0
    ns = 0
    flying = True
    for k in range(n_ctrl + 1):
        x, yy, z, vx, vy, vz, s, a, b, c, w1, w2, w3, fuel = st
        if not (math.isfinite(x) and math.isfinite(w1) and math.isfinite(yy) and math.isfinite(w2)
                and math.isfinite(z) and math.isfinite(w3)):
            break
        rn = math.sqrt(x * x + yy * yy + z * z)
        up_r = 2.0 * (s * b + a * c) * x + 2.0 * (b * c - s * a) * yy + (s * s - a * a - b * b + c * c) * z
        err[k] = (rn - MARS_RADIUS) - d_alt
        tilt[k] = math.acos(max(-1.0, min(1.0, up_r / rn)))
        rate[k] = math.sqrt(w1 * w1 + w2 * w2 + w3 * w3)
        ns = k + 1
        if not flying or k == n_ctrl:
            break
        # The law (law_update's operations): altitude eq 18-19, attitude eq 28, priority mixing.
        r = math.sqrt(x * x + yy * yy + z * z)
        h = r - MARS_RADIUS
        hd = (vx * x + vy * yy + vz * z) / r
        m = l_dry + fuel
        rr = h + MARS_RADIUS
        u_alt = m / l_tv * (GM_MARS / (rr * rr) - k0 * (h - d_alt) - k1 * hd)
        r00 = s * s + a * a - b * b - c * c
        r01 = 2.0 * (a * b + s * c)
        r02 = 2.0 * (a * c - s * b)
        r12 = 2.0 * (s * a + b * c)
        r20 = 2.0 * (s * b + a * c)
        r21 = 2.0 * (b * c - s * a)
        r22 = s * s - a * a - b * b + c * c
        sth = math.hypot(r20, r21)
        e1 = math.atan2(sth, r22)
        if sth > 1e-12:
            e0, e2 = math.atan2(r20, -r21), math.atan2(r02, r12)
        else:
            e0, e2 = math.atan2(r01, r00), 0.0
        e = (_wrap(e0 - d_e0), e1 - d_e1, _wrap(e2 - d_e2), w1 - d_w0, w2 - d_w1, w3 - d_w2)
        scale = (l_dry + fuel) / l_mass if l_scaled else 1.0
        lo = math.inf
        hi = -math.inf
        for i in range(n):
            acc = 0.0
            for j in range(6):
                acc += K[i, j] * e[j]
            u[i] = u_alt + (-scale) * acc
            lo = min(lo, u[i]) if i > 0 else u[i]
            hi = max(hi, u[i]) if i > 0 else u[i]
        mixed = False
        if not (lo >= 0.0 and hi <= 1.0):
            cm = u_alt
            for _ in range(1, n):
                cm += u_alt
            cm = cm / n
            dlo = lo - cm
            dhi = hi - cm
            span = dhi - dlo
            shrink = span > 1.0
            if shrink:
                dlo, dhi = dlo / span, dhi / span
            c_fit = min(max(cm, -dlo), 1.0 - dhi)
            for i in range(n):
                d = u[i] - cm
                if shrink:
                    d = d * (1.0 / span)
                u[i] = c_fit + d
            mixed = True
            lo = u[0]
            hi = u[0]
            for i in range(1, n):
                lo = min(lo, u[i])
                hi = max(hi, u[i])
        for i in range(n):
            u[i] = min(max(u[i], 0.0), 1.0)
        sats += mixed or lo < -1e-9 or hi > 1.0 + 1e-9
        # The thrusters' sums at these throttles, in the kernel's order; one Verlet step.
        fbx = fby = fbz = qx = qy = qz = use = 0.0
        for i in range(n):
            t = u[i]
            fbx += t * force[i, 0]
            fby += t * force[i, 1]
            fbz += t * force[i, 2]
            qx += t * torque[i, 0]
            qy += t * torque[i, 1]
            qz += t * torque[i, 2]
        for i in range(n):
            use += u[i] * burn[i]
        ct = (kc[0], kc[1], kc[2], kc[3], kc[4], kc[5], kc[6], kc[7], kc[8], kc[9], kc[10],
              fbx, fby, fbz, qx, qy, qz, -use, kc[18], kc[19], kc[20], 1.0)
        st = ceiling.ceiling_step(st, dt, ct)
        if stop2 > 0.0 and st[0] * st[0] + st[1] * st[1] + st[2] * st[2] < stop2:
            flying = False
        if st[13] <= 0.0:
            break  # the fuel-out of the product is not this flight's: stop (agreement then fails)
    for j in range(14):
        y_out[j] = st[j]
    return ns, sats


def flight() -> dict:
    """The bench flight packed as the product packs it, and the ceiling's inputs from the same arrays."""
    from lander_autopilot.controllers import Demand, make_controller
    from lander_autopilot.controllers.compiled import D_ALT, D_E0, D_W0, AltitudeLaw, AttitudeLaw, compiled_form
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation
    from lander_tools.sweep import batched

    scene = load_scene(SCENE)
    law = compiled_form(make_controller(LAW, scene.vehicle))
    assert law is not None
    if (law.altitude, law.attitude, law.summed, law.attitude_priority) != (AltitudeLaw.STATE_FEEDBACK, AttitudeLaw.EULER, True, True):
        raise ValueError(f"the loop ceiling is the {LAW!r} law of altitude + Euler attitude with priority; got {law}")
    sim = Simulation(scene)
    n = int(round(DURATION / scene.dt))
    alt = Demand().altitude
    # The public names; a revision that predates them (timed by the guard) had them underscored.
    pack = getattr(batched, "pack_flights", None) or batched._pack
    setup = getattr(batched, "FlightSetup", None) or batched._Flight
    inputs = pack([setup(-1, batched.FlightCase(-1, 0), sim, (alt, alt, 0.0))], n)
    if inputs["gust_ab"][0, 0] != 0.0 or np.any(inputs["fail_step"][0] >= 0):
        raise ValueError("the loop ceiling flies no gusts and no thruster failures")
    fl = sim.fast_kernel
    wind = inputs["mean_wind"][0] + inputs["gust_g0"][0]  # the product's wind at every step (no gust process)
    kc = ceiling.constants(fl, np.zeros(inputs["force"].shape[1]), wind)
    d = inputs["d_after"][0]
    params, K = law.pack()
    lp = np.array([law.dry_mass, law.T_v, law.k_altitude[0], law.k_altitude[1], law.attitude_design_mass,
                   1.0 if law.attitude_mass_scaled else 0.0])
    dem = np.array([d[D_ALT], *d[D_E0:D_E0 + 3], *d[D_W0:D_W0 + 3]])
    return {"inputs": inputs, "params": params, "K": K, "n": n, "dt": scene.dt, "stop": sim.ground.contact_radius,
            "kc": kc, "law": lp, "dem": dem}


def run_product(f: dict, copies: int) -> dict:
    from lander_tools.sweep import batched_kernel as bk

    inputs = {k: np.repeat(v, copies, axis=0) for k, v in f["inputs"].items()}
    return bk.fly_flights(inputs, f["params"], f["K"], f["n"], 1, f["dt"], f["dt"], f["stop"], parallel=False,
                          record_states=copies == 1)


def run_ceiling(f: dict, copies: int) -> tuple[np.ndarray, ...]:
    inp = f["inputs"]
    err, tilt, rate, y = np.zeros(f["n"] + 1), np.zeros(f["n"] + 1), np.zeros(f["n"] + 1), np.zeros(14)
    for _ in range(copies):
        ns, sats = loop_ceiling(inp["y0"][0], f["kc"], inp["force"][0], inp["torque"][0], inp["burn"][0], f["law"], f["K"],
                                f["dem"], f["n"], f["dt"], f["stop"], err, tilt, rate, y)
    return err, tilt, rate, y, np.array([ns, sats])


def agreement(f: dict) -> float:
    """Largest relative difference of the samples and the last state, ceiling vs product (0: bit for bit)."""
    p = run_product(f, 1)
    err, tilt, rate, y, counts = run_ceiling(f, 1)
    ns = int(p["n_samples"][0])
    pairs = [(err, p["err"][0]), (tilt, p["tilt"][0]), (rate, p["rate"][0]), (y, p["states"][0][ns - 1])]
    worst = max(float(np.max(np.abs(a[:ns] - b[:ns]) / np.maximum(np.abs(b[:ns]), 1e-300))) for a, b in pairs[:3])
    worst = max(worst, float(np.max(np.abs(y - pairs[3][1]) / np.maximum(np.abs(pairs[3][1]), 1e-300))))
    if counts[0] != ns or counts[1] != p["sats"][0]:
        return math.inf
    return worst


def time_side_by_side(f: dict, copies: int, rounds: int) -> dict[str, float]:
    """Loops per second of the product's loop and the ceiling, alternating; medians and their ratio."""
    run_product(f, 2)
    run_ceiling(f, 1)  # compile (or load) both outside the timing
    rates: dict[str, list[float]] = {"product": [], "ceiling": []}
    for _ in range(rounds):
        for name in rates:
            t0 = time.perf_counter()
            run_product(f, copies) if name == "product" else run_ceiling(f, copies)
            rates[name].append(copies * f["n"] / (time.perf_counter() - t0))
    p, c = statistics.median(rates["product"]), statistics.median(rates["ceiling"])
    return {"compiled_loops_per_s": p, "ceiling_loops_per_s": c, "loop_over_ceiling": p / c, "rounds": rounds}


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    if not HAVE_NUMBA:
        print("numba missing: no ceiling to measure")
        return 1
    f = flight()
    res: dict[str, float | int | bool] = time_side_by_side(f, 50 if args.quick else 300, 3 if args.quick else 7)
    rel = agreement(f)
    res.update({"ceiling_vs_loop_max_rel": rel, "bitwise_equal": rel == 0.0})
    print(C.table(f"closed loop, one flight of {SCENE} with {LAW!r}, one thread: product vs ceiling alternating, medians of {res['rounds']}",
                  ["loop", "loops/s", "x ceiling"],
                  [["compiled closed loop (lander_tools.sweep.batched_kernel)", f"{res['compiled_loops_per_s']:.0f}", res["loop_over_ceiling"]],
                   ["ceiling (bench/ceiling_loop.py)", f"{res['ceiling_loops_per_s']:.0f}", 1.0]]))
    print(f"ceiling vs product, samples and last state: max relative difference {rel:.3g} "
          f"({'bit for bit' if res['bitwise_equal'] else 'NOT bit for bit'})")
    C.write_json(args.json, res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
