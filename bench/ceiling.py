"""What this machine can do: a minimal fused velocity-Verlet loop of the hover scene, timed beside the kernel.

The product's compiled kernel (:func:`lander_sim.fast.lander_kernel.verlet_steps`) is general: its
parameters array switches models, attitude mode and mount on and off, and it reads throttles,
wind and thruster tables from arrays. :func:`ceiling_steps` is the same physics of the hover scene
written only to be fast and used by nothing in the product: every switch decided (inverse-square
gravity, exponential atmosphere, sphere drag in a fixed wind, four thrusters at fixed throttles,
quaternion attitude renormalised each step, inertia ``m diag(k^2)``), the thrusters' summed force,
torque and fuel rate taken once per call (the throttles are constant over a call, as they are over
one call of the kernel), and the whole state held in local scalars through the loop. Every
expression keeps the kernel's operation order, so the two agree bit for bit (IEEE 754 arithmetic
of the same operations in the same order; numba does not reassociate or fuse without fastmath),
which :func:`agreement` measures.

Equations as the kernel's: gravity ``F_W = -GM m r / |r|^3`` (eq 7 of the control reference),
``rho = rho0 exp(-h/H)`` below the exosphere, drag ``1/2 rho Cd A |W| W`` with ``W = wind_W - v_W``,
``a_W = (F_W + R(q)^T F_B) / m`` (eq 13), Euler's equations (eq 1-2), quaternion by eq 14.

    python bench/ceiling.py [--json FILE] [--quick]
"""
from __future__ import annotations

import math
import statistics
import sys
import time

import _common as C
import numpy as np

from lander_sim import fast
from lander_sim.fast import lander_kernel as K
from lander_sim.fast.lander_kernel import HAVE_NUMBA, njit  # numba's, or the plain-Python stand-in
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation

DT = 0.01
THROTTLES = [0.5, 0.48, 0.52, 0.5]  # as bench/speed.py
WIND = [3.0, 1.0, -2.0]
CHUNK = 1000  # steps per call (10 s of hover), from the same start each call, as bench/speed.py


@njit(cache=True, error_model="numpy")
def accelerations(x, yy, z, vx, vy, vz, s, a, b, c, w1, w2, w3, fuel, gm, rp, rho0, scale_h, exo, cd, area, dry, k1, k2, k3,
         fbx0, fby0, fbz0, qx0, qy0, qz0, wind0, wind1, wind2):  # pragma: no cover - compiled
    """(a_W, omega_dot_B) of one state, in the kernel's operation order."""
    mass = dry + fuel
    r2 = x * x + yy * yy + z * z
    k = -gm * mass / (r2 * math.sqrt(r2))
    fwx = 0.0 + k * x
    fwy = 0.0 + k * yy
    fwz = 0.0 + k * z
    rho = 0.0
    alt = math.sqrt(x * x + yy * yy + z * z) - rp
    if alt <= exo:
        rho = rho0 * math.exp(-alt / scale_h)
    if rho != 0.0:
        wx, wy, wz = wind0 - vx, wind1 - vy, wind2 - vz
        kd = 0.5 * rho * cd * area * math.sqrt(wx * wx + wy * wy + wz * wz)
        fwx += kd * wx
        fwy += kd * wy
        fwz += kd * wz
    fbx = fby = fbz = qx = qy = qz = 0.0
    if fuel > 0.0:
        fbx, fby, fbz, qx, qy, qz = fbx0, fby0, fbz0, qx0, qy0, qz0
    r00 = s * s + a * a - b * b - c * c
    r01 = 2.0 * (a * b + s * c)
    r02 = 2.0 * (a * c - s * b)
    r10 = 2.0 * (a * b - s * c)
    r11 = s * s - a * a + b * b - c * c
    r12 = 2.0 * (s * a + b * c)
    r20 = 2.0 * (s * b + a * c)
    r21 = 2.0 * (b * c - s * a)
    r22 = s * s - a * a - b * b + c * c
    ax = (fwx + (r00 * fbx + r10 * fby + r20 * fbz)) / mass
    ay = (fwy + (r01 * fbx + r11 * fby + r21 * fbz)) / mass
    az = (fwz + (r02 * fbx + r12 * fby + r22 * fbz)) / mass
    A, B, Cc = mass * k1, mass * k2, mass * k3
    return (ax, ay, az, ((B - Cc) * w2 * w3 + qx) / A, ((Cc - A) * w3 * w1 + qy) / B, ((A - B) * w1 * w2 + qz) / Cc)


@njit(cache=True, error_model="numpy")
def ceiling_step(st, dt, c):  # pragma: no cover - compiled
    """One step from the 14 state values ``st``: the 14 after it. ``c``: the 22 constants of
    :func:`constants` as a tuple."""
    x, yy, z, vx, vy, vz, s, a, b, cq, w1, w2, w3, fuel = st
    gm, rp, rho0, scale_h, exo, cd, area, dry, k1, k2, k3 = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10]
    fbx0, fby0, fbz0, qx0, qy0, qz0, burn0 = c[11], c[12], c[13], c[14], c[15], c[16], c[17]
    wind0, wind1, wind2 = c[18], c[19], c[20]
    h = 0.5 * dt
    a0 = accelerations(x, yy, z, vx, vy, vz, s, a, b, cq, w1, w2, w3, fuel, gm, rp, rho0, scale_h, exo, cd, area, dry,
                       k1, k2, k3, fbx0, fby0, fbz0, qx0, qy0, qz0, wind0, wind1, wind2)
    fuel_rate = burn0 if fuel > 0.0 else 0.0
    wh1 = w1 + h * a0[3]
    wh2 = w2 + h * a0[4]
    wh3 = w3 + h * a0[5]
    ds = 0.5 * (-a * wh1 - b * wh2 - cq * wh3)
    da = 0.5 * (s * wh1 + b * wh3 - cq * wh2)
    db = 0.5 * (s * wh2 + cq * wh1 - a * wh3)
    dc = 0.5 * (s * wh3 + a * wh2 - b * wh1)
    s = s + ds * dt
    a = a + da * dt
    b = b + db * dt
    cq = cq + dc * dt
    nq = math.sqrt(s * s + a * a + b * b + cq * cq)
    s, a, b, cq = s / nq, a / nq, b / nq, cq / nq
    vh0 = vx + h * a0[0]
    vh1 = vy + h * a0[1]
    vh2 = vz + h * a0[2]
    x = x + vh0 * dt
    yy = yy + vh1 * dt
    z = z + vh2 * dt
    fuel += fuel_rate * dt
    if fuel < 0.0:
        fuel = 0.0
    a1 = accelerations(x, yy, z, vx + dt * a0[0], vy + dt * a0[1], vz + dt * a0[2], s, a, b, cq,
                       w1 + dt * a0[3], w2 + dt * a0[4], w3 + dt * a0[5], fuel, gm, rp, rho0, scale_h, exo, cd, area, dry,
                       k1, k2, k3, fbx0, fby0, fbz0, qx0, qy0, qz0, wind0, wind1, wind2)
    return (x, yy, z, vh0 + h * a1[0], vh1 + h * a1[1], vh2 + h * a1[2], s, a, b, cq,
            wh1 + h * a1[3], wh2 + h * a1[4], wh3 + h * a1[5], fuel)


@njit(cache=True, error_model="numpy")
def ceiling_steps(y, y_prev, n, dt, c, stop_radius):  # pragma: no cover - compiled
    """Up to ``n`` steps of ``y`` in place; ``c``: the constants of :func:`constants`. As ``verlet_steps``."""
    ct = (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12], c[13], c[14], c[15], c[16],
          c[17], c[18], c[19], c[20], c[21])
    burning = c[21] != 0.0
    stop2 = stop_radius * stop_radius
    st = (y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9], y[10], y[11], y[12], y[13])
    p = st
    taken = n
    for k in range(n):
        p = st
        st = ceiling_step(st, dt, ct)
        if (stop2 > 0.0 and st[0] * st[0] + st[1] * st[1] + st[2] * st[2] < stop2) or (burning and st[13] <= 0.0):
            taken = k + 1
            break
    for j in range(14):
        y[j] = st[j]
        y_prev[j] = p[j]
    return taken


def constants(fl: fast.FastLander, throttles: np.ndarray, wind: np.ndarray) -> np.ndarray:
    """The ceiling's constants from a :class:`~lander_sim.fast.FastLander` of the hover scene and its inputs.

    The thrusters' sums are formed in the kernel's order (``0 + t_0 F_0 + t_1 F_1 + ...``), so
    they are the values the kernel forms at every evaluation. Raises if the lander has a switch
    the ceiling decided otherwise (the ceiling is the hover scene's physics only).
    """
    p = fl.params
    want = {"P_GRAV": 1.0, "P_ATMO": 1.0, "P_DRAG": 1.0, "P_THRUST": 1.0, "P_RENORM": 1.0, "P_FIXED_I": 0.0,
            "P_UGRAV": 0.0, "P_CFORCE": 0.0, "P_EULER": 0.0, "P_PIVOT": 0.0}
    # A switch the kernel's layout does not have (an older kernel) is off there.
    wrong = [name for name, v in want.items() if hasattr(K, name) and p[getattr(K, name)] != v]
    if wrong:
        raise ValueError(f"the ceiling is the hover scene's physics; parameter slots {wrong} differ")
    sums = [0.0] * 7
    for i in range(throttles.shape[0]):
        t = float(throttles[i])
        for j in range(3):
            sums[j] += t * float(fl.force[i, j])
            sums[3 + j] += t * float(fl.torque[i, j])
        sums[6] += t * float(fl.burn[i])
    return np.array([p[K.P_GM], p[K.P_RPLANET], p[K.P_RHO0], p[K.P_H], p[K.P_EXO], p[K.P_CD], p[K.P_AREA], p[K.P_DRY],
                     p[K.P_K1], p[K.P_K2], p[K.P_K3], *sums[:6], -sums[6], *(float(w) for w in wind),
                     1.0 if np.any(throttles != 0.0) else 0.0])


def hover_lander() -> tuple[fast.FastLander, np.ndarray, np.ndarray]:
    """(fast lander, initial state, ceiling constants) of the hover scene with bench/speed.py's inputs."""
    sim = Simulation(load_scene("hover"), dt=DT)
    sim.set_throttles(THROTTLES)
    sim.set_wind(WIND)
    fl = fast.FastLander(sim.dynamics)
    return fl, sim.y.copy(), constants(fl, np.asarray(THROTTLES, dtype=float), np.asarray(WIND, dtype=float))


def agreement(fl: fast.FastLander, y0: np.ndarray, c: np.ndarray, n: int) -> tuple[float, int, int]:
    """(max relative difference of the states, steps kernel, steps ceiling) after ``n`` steps from ``y0``."""
    yk, yc, pk, pc = y0.copy(), y0.copy(), np.empty(14), np.empty(14)
    nk = fl.advance(yk, pk, DT, n)
    nc = ceiling_steps(yc, pc, n, DT, c, 0.0)
    scale = np.maximum(np.abs(yk), 1e-300)
    return float(np.max(np.abs(yc - yk) / scale)), int(nk), int(nc)


def time_side_by_side(fl: fast.FastLander, y0: np.ndarray, c: np.ndarray, chunks: int, rounds: int) -> dict[str, float]:
    """Steps per second of the kernel and the ceiling, alternating ``rounds`` times; medians and their ratio."""
    y, yp = y0.copy(), np.empty(14)
    fl.advance(y, yp, DT, 10)
    ceiling_steps(y, yp, 10, DT, c, 0.0)  # compile or load both outside the timing
    rates: dict[str, list[float]] = {"kernel": [], "ceiling": []}
    for _ in range(rounds):
        for name in rates:
            taken = 0
            t0 = time.perf_counter()
            for _ in range(chunks):
                y[:] = y0
                taken += fl.advance(y, yp, DT, CHUNK) if name == "kernel" else ceiling_steps(y, yp, CHUNK, DT, c, 0.0)
            rates[name].append(taken / (time.perf_counter() - t0))
    k, cl = statistics.median(rates["kernel"]), statistics.median(rates["ceiling"])
    return {"kernel_steps_per_s": k, "ceiling_steps_per_s": cl, "kernel_over_ceiling": k / cl, "rounds": rounds}


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    if not HAVE_NUMBA:
        print("numba missing: no ceiling to measure")
        return 1
    fl, y0, c = hover_lander()
    res: dict[str, float | int | bool] = time_side_by_side(fl, y0, c, 50 if args.quick else 300, 3 if args.quick else 7)
    rel, nk, nc = agreement(fl, y0, c, CHUNK)
    res.update({"ceiling_vs_kernel_max_rel": rel, "bitwise_equal": rel == 0.0 and nk == nc, "agreement_steps": CHUNK})
    print(C.table(f"velocity-Verlet steps per second, hover scene, one core: kernel vs ceiling alternating, medians of {res['rounds']}",
                  ["implementation", "steps/s", "x ceiling"],
                  [["compiled kernel (lander_sim.fast)", f"{res['kernel_steps_per_s']:.0f}", res["kernel_over_ceiling"]],
                   ["ceiling (bench/ceiling.py)", f"{res['ceiling_steps_per_s']:.0f}", 1.0]]))
    print(f"ceiling vs kernel after {CHUNK} steps: max relative difference {rel:.3g} "
          f"({'bit for bit' if res['bitwise_equal'] else 'NOT bit for bit'}; steps {nk} / {nc})")
    C.write_json(args.json, res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
