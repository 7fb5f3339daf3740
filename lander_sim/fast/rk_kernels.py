"""Compiled Runge-Kutta methods for the standard lander model: RK4, Dormand-Prince 5(4), DOP853.

The model is the one of :mod:`lander_sim.fast.lander_kernel` (inverse-square or uniform gravity,
exponential atmosphere, sphere drag, thrusters, a constant force at a body point: the seed-1
rotor and pendulum; any subset, also none: the torque-free top) in quaternion or ZXZ Euler-angle
mode, with or without translation (a fixed pivot), written as the first-order form of
:func:`lander_sim.integrators.base.derivative`: ``r' = v``, ``v' = a_W``, ``q' = 1/2 q x (0, omega)``
(eq 14) or ``E' = J(E) omega`` (eq 5, ``sin theta`` floored as the numpy path floors it, slot 9
held at 0), ``omega' `` from Euler's equations (eq 2), ``fuel' = -sum t_i burn_i``.

* :func:`rk4_steps`: ``n`` steps of :class:`lander_sim.integrators.rk4.RK4` (same operation order,
  the quaternion (never Euler angles) renormalised and fuel clamped after each step).
* :func:`dopri5_span`: one call of :class:`lander_sim.integrators.adaptive.AdaptiveDormandPrince`
  in local error control (same tableau, error norm HNW II eq 4.11, controller, last-step stretch,
  FSAL within the call).
* :func:`dop853_span`: Dormand-Prince 8(5,3) exactly as scipy's ``solve_ivp(method="DOP853")``
  steps it (Hairer, Norsett & Wanner, *Solving ODEs I*, II.5 and II.4: the same tableau, the
  combined 5th/3rd-order error estimate, the initial-step guess and the step-size controller), so
  scipy's DOP853 is its reference.
* :func:`geometric_steps`: the DLM splitting of :class:`lander_sim.integrators.geometric.Geometric`,
  quaternion mode only (it moves the attitude by the exponential map; Euler angles have none).

The numpy integrators stay the reference for the first two; tests hold each pair to 1e-12.
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from lander_sim.fast import lander_kernel as _k
from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import njit  # type: ignore[attr-defined]  # numba's, or the no-numba stand-in
from lander_sim.integrators.dormand_prince import DP_A, DP_C, DP_E

# These kernels call lander_kernel's and the free rotor, and hold the Dormand-Prince tableau: recompile when those change.
invalidate_if_changed(__file__, _k.__file__, str(Path(__file__).parents[1] / "integrators" / "free_rotor.py"),
                      str(Path(__file__).parents[1] / "integrators" / "dormand_prince.py"))

__all__ = ["CompiledModel", "compiled_model", "dop853_span", "dop853_tableau", "dopri5_span", "rk4_steps", "unsupported_model"]


def unsupported_model(dyn: Any) -> str | None:
    """Why ``dyn`` has no compiled form (None if it has one: a
    :class:`~lander_sim.physics.dynamics.LanderDynamics` of the supported models, in quaternion
    or ZXZ Euler-angle attitude)."""
    from lander_sim.physics.dynamics import LanderDynamics

    if not isinstance(dyn, LanderDynamics):
        return f"{type(dyn).__name__} is not a LanderDynamics (its equations are its own)"
    if getattr(dyn, "attitude", None) not in ("quaternion", "euler"):
        return f"attitude {getattr(dyn, 'attitude', None)!r} (compiled methods know quaternion and euler)"
    names = {m.name: m for m in getattr(dyn, "models", ())}
    unknown = set(names) - {"gravity", "drag", "thrusters", "parachute", "constant_force"}
    if unknown:
        return f"model(s) {', '.join(sorted(unknown))}"
    if "drag" in names and not hasattr(names["drag"], "cd"):
        return "mesh drag (compiled methods have sphere drag only)"
    chute = names.get("parachute")
    if chute is not None and getattr(chute.status, "value", "") == "deployed":
        return "deployed parachute"
    v = dyn.vehicle
    if v.gyration_sq is None and v.inertia_diag is None:
        return "vehicle without inertia"
    return None


class CompiledModel:
    """A dynamics' parameters packed for the kernels (layout of :mod:`lander_kernel`); inputs are
    read from the dynamics' shared ``inputs`` at each call."""

    def __init__(self, dyn: Any) -> None:
        why = unsupported_model(dyn)
        if why is not None:
            raise ValueError(f"no compiled form of this model: {why}")
        from lander_sim.physics.rotation import SIN_THETA_FLOOR

        p = np.zeros(_k.N_PARAMS)
        names = {m.name: m for m in dyn.models}
        if dyn.attitude == "euler":
            p[_k.P_EULER] = 1.0
            p[_k.P_SIN_FLOOR] = SIN_THETA_FLOOR  # the numpy path's floor, read at packing time
        if not dyn.translation:
            p[_k.P_PIVOT] = 1.0
        g = names.get("gravity")
        if g is not None and hasattr(g, "gm"):
            p[_k.P_GRAV], p[_k.P_GM] = 1.0, g.gm
        elif g is not None:
            p[_k.P_UGRAV] = 1.0
            p[_k.P_G0:_k.P_G0 + 3] = g.g_W
        cf = names.get("constant_force")
        if cf is not None:
            p[_k.P_CFORCE] = 1.0
            p[_k.P_CF0:_k.P_CF0 + 3] = cf.force_W
            p[_k.P_CP0:_k.P_CP0 + 3] = cf.point_B
        p[_k.P_RPLANET] = dyn.planet_radius
        if dyn.atmosphere is not None:
            p[_k.P_ATMO] = 1.0
            p[_k.P_RHO0], p[_k.P_H], p[_k.P_EXO] = (dyn.atmosphere.surface_density, dyn.atmosphere.scale_height,
                                                    dyn.atmosphere.exosphere)
        d = names.get("drag")
        if d is not None:
            p[_k.P_DRAG], p[_k.P_CD], p[_k.P_AREA] = 1.0, d.cd, d.area
        v = dyn.vehicle
        p[_k.P_DRY] = v.dry_mass
        if v.gyration_sq is not None:
            p[_k.P_K1], p[_k.P_K2], p[_k.P_K3] = v.gyration_sq
        else:
            p[_k.P_FIXED_I] = 1.0
            p[_k.P_K1], p[_k.P_K2], p[_k.P_K3] = v.inertia_diag
        n = v.n_thrusters
        self.force, self.torque, self.burn = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
        th = names.get("thrusters")
        if th is not None:
            p[_k.P_THRUST] = 1.0
            self.force = np.ascontiguousarray(th._force, dtype=float)
            self.torque = np.ascontiguousarray(th._torque, dtype=float)
            self.burn = np.ascontiguousarray(th._burn, dtype=float)
        self.params = p
        self.translation = 1.0 if dyn.translation else 0.0
        self.dyn = dyn
        self.chute = names.get("parachute")

    def verlet_params(self, renormalise: bool) -> np.ndarray:
        """The parameters with the Verlet kernel's renormalisation switch set."""
        key = "_verlet_on" if renormalise else "_verlet_off"
        p = getattr(self, key, None)
        if p is None:
            p = self.params.copy()
            p[_k.P_RENORM] = 1.0 if renormalise else 0.0
            setattr(self, key, p)
        return p

    def inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """``(throttles, wind_W)`` in force, as contiguous float arrays."""
        i = self.dyn.inputs
        return np.ascontiguousarray(i.throttles, dtype=float), np.ascontiguousarray(i.wind_W, dtype=float)


def compiled_model(dyn: Any) -> CompiledModel | None:
    """The dynamics' :class:`CompiledModel` (cached on the dynamics object), or None."""
    cm = getattr(dyn, "_compiled_model", None)
    if cm is not None and cm.dyn is dyn:
        # Only the parachute can change at run time (deployed: the kernels do not model it).
        return None if cm.chute is not None and getattr(cm.chute.status, "value", "") == "deployed" else cm
    if unsupported_model(dyn) is not None:
        return None
    cm = CompiledModel(dyn)
    try:
        dyn._compiled_model = cm
    except AttributeError:  # pragma: no cover - a slotted dynamics: rebuilt each time
        pass
    return cm


@njit(cache=True)
def derivative(y, P, force, torque, burn, thr, wind, trans, out, acc):  # pragma: no cover - compiled
    """First-order form ``out = f(y)`` (inputs constant; the model has no explicit time)."""
    _k._accelerations(y, P, force, torque, thr, wind, acc)
    if trans != 0.0:
        out[0], out[1], out[2] = y[3], y[4], y[5]
        out[3], out[4], out[5] = acc[0], acc[1], acc[2]
    else:
        for j in range(6):
            out[j] = 0.0
    if P[_k.P_EULER] != 0.0:
        # eq 5, E' = J(E) omega (rotation.euler_rates_matrix @ omega); slot 9 is unused in this mode.
        out[6], out[7], out[8] = _k.euler_rates(y, P[_k.P_SIN_FLOOR])
        out[9] = 0.0
    else:
        # eq 14, q' = 1/2 q x (0, omega) (rotation.quat_dot).
        s, a, b, c = y[6], y[7], y[8], y[9]
        wx, wy, wz = y[10], y[11], y[12]
        out[6] = 0.5 * (-a * wx - b * wy - c * wz)
        out[7] = 0.5 * (s * wx + b * wz - c * wy)
        out[8] = 0.5 * (s * wy + c * wx - a * wz)
        out[9] = 0.5 * (s * wz + a * wy - b * wx)
    out[10], out[11], out[12] = acc[3], acc[4], acc[5]
    rate = 0.0
    if P[_k.P_THRUST] != 0.0 and y[13] > 0.0:
        for i in range(thr.shape[0]):
            rate += thr[i] * burn[i]
        rate = -rate
    out[13] = rate


@njit(cache=True)
def _renormalise(y):  # pragma: no cover - compiled
    n = math.sqrt(y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9])
    for j in range(6, 10):
        y[j] = y[j] / n


@njit(cache=True)
def rk4_steps(y, dt, n, P, force, torque, burn, thr, wind, trans, renormalise):  # pragma: no cover - compiled
    """``n`` classical RK4 steps of ``dt`` [s] of ``y`` in place (as :class:`~lander_sim.integrators.rk4.RK4`);
    ``renormalise`` applies to a quaternion only (Euler angles are not a unit vector)."""
    k = np.empty((4, 14))
    tmp = np.empty(14)
    acc = np.empty(6)
    h = 0.5 * dt
    w = dt / 6.0
    for _ in range(n):
        derivative(y, P, force, torque, burn, thr, wind, trans, k[0], acc)
        for j in range(14):
            tmp[j] = k[0, j] * h + y[j]
        derivative(tmp, P, force, torque, burn, thr, wind, trans, k[1], acc)
        for j in range(14):
            tmp[j] = k[1, j] * h + y[j]
        derivative(tmp, P, force, torque, burn, thr, wind, trans, k[2], acc)
        for j in range(14):
            tmp[j] = k[2, j] * dt + y[j]
        derivative(tmp, P, force, torque, burn, thr, wind, trans, k[3], acc)
        for j in range(14):
            y[j] += w * (((k[0, j] + 2.0 * k[1, j]) + 2.0 * k[2, j]) + k[3, j])
        if renormalise and P[_k.P_EULER] == 0.0:
            _renormalise(y)
        if y[13] < 0.0:  # noqa: PLR1730 - as clamp_fuel: a NaN stays NaN (max() would hide it)
            y[13] = 0.0
    return 4 * n


# Dormand-Prince 5(4): the tableau of lander_sim.integrators.adaptive (Dormand & Prince 1980) as arrays.
_DP_C = np.array(DP_C)
_DP_A = np.zeros((7, 6))
for _i, _row in enumerate(DP_A):
    _DP_A[_i, :len(_row)] = _row
_DP_E = np.array(DP_E)


@njit(cache=True)
def _dp_stages(y, h, k, tmp, P, force, torque, burn, thr, wind, trans, A, acc):  # pragma: no cover - compiled
    """Stages 2-6 of a Dormand-Prince step (``k[0] = f(y)`` given); the 5th-order solution in ``tmp``."""
    for i in range(1, 7):
        for j in range(14):
            tmp[j] = y[j]
        for m in range(i):
            a = A[i, m]
            if a != 0.0:
                f = h * a
                for j in range(14):
                    tmp[j] += f * k[m, j]
        if i < 6:
            derivative(tmp, P, force, torque, burn, thr, wind, trans, k[i], acc)


@njit(cache=True)
def dopri5_span(y, t0, dt, rtol, atol, h_in, P, force, torque, burn, thr, wind, trans, A, C, E, stats, fine, use_fine):  # pragma: no cover - compiled
    """Advance ``y`` in place from ``t0`` by exactly ``dt`` [s] under local error control, as one local-mode call of
    :class:`~lander_sim.integrators.adaptive.AdaptiveDormandPrince` (``h_in <= 0``: initial guess).

    With ``use_fine``, ``fine`` (equal to ``y`` on entry) is advanced in parallel by two half
    steps per accepted step: the bisected mesh of the global error control.
    Returns the step size kept for the next call (negative: the step size underflowed, -inf: too
    many internal steps; the caller raises); ``stats`` gets ``[accepted, rejected, evaluations,
    last error, max error]`` added (the last two overwritten / maxed). No renormalisation here.
    """
    k = np.empty((7, 14))
    tmp = np.empty(14)
    ynew = np.empty(14)
    acc = np.empty(6)
    t = t0
    t_end = t0 + dt
    derivative(y, P, force, torque, burn, thr, wind, trans, k[0], acc)
    ev = 1
    kf = np.empty((7, 14))
    if use_fine:
        for j in range(14):
            kf[0, j] = k[0, j]  # fine == y on entry
    h = h_in
    if h <= 0.0:
        s0 = 0.0
        s1 = 0.0
        for j in range(14):
            sc = atol + rtol * abs(y[j])
            s0 += (y[j] / sc) ** 2
            s1 += (k[0, j] / sc) ** 2
        d0 = math.sqrt(s0 / 14.0)
        d1 = math.sqrt(s1 / 14.0)
        h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h = min(h, dt)
    done = False
    for _ in range(1_000_000):
        remaining = t_end - t
        last = 1.01 * h >= remaining
        hs = remaining if last else h
        _dp_stages(y, hs, k, tmp, P, force, torque, burn, thr, wind, trans, A, acc)
        ev += 5
        for j in range(14):
            ynew[j] = tmp[j]
        derivative(ynew, P, force, torque, burn, thr, wind, trans, k[6], acc)
        ev += 1
        ssum = 0.0
        for j in range(14):
            e = 0.0
            for m in range(7):
                if E[m] != 0.0:
                    e += (hs * E[m]) * k[m, j]
            sc = atol + rtol * max(abs(y[j]), abs(ynew[j]))
            ssum += (e / sc) ** 2
        en = math.sqrt(ssum / 14.0)
        if en <= 1.0:
            stats[0] += 1
            stats[3] = en
            stats[4] = max(stats[4], en)
            if use_fine:  # global mode: the bisected mesh, two half steps (FSAL) per accepted step
                half = 0.5 * hs
                for _ in range(2):
                    _dp_stages(fine, half, kf, tmp, P, force, torque, burn, thr, wind, trans, A, acc)
                    for j in range(14):
                        fine[j] = tmp[j]
                    derivative(fine, P, force, torque, burn, thr, wind, trans, kf[6], acc)
                    for j in range(14):
                        kf[0, j] = kf[6, j]
                ev += 12
            for j in range(14):
                y[j] = ynew[j]
                k[0, j] = k[6, j]
            t = t_end if last else t + hs
            fac = 5.0 if en == 0.0 else min(5.0, max(0.2, 0.9 * en ** -0.2))
            h = max(h, hs * fac) if fac >= 1.0 else hs * fac
            if last:
                done = True
                break
        else:
            stats[1] += 1
            h = hs * max(0.2, 0.9 * en ** -0.2)
            if h < 1e-14 * max(1.0, abs(t)):
                stats[2] += ev
                return -h  # underflow: the caller raises
    stats[2] += ev
    return h if done else -math.inf  # -inf: too many internal steps, the caller raises


def dopri5_tableau() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, C, E)`` of Dormand-Prince 5(4) for :func:`dopri5_span`."""
    return _DP_A, _DP_C, _DP_E


@lru_cache(maxsize=1)
def dop853_tableau() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C, E3, E5)`` of DOP853, scipy's own coefficients (HNW's ``dop853.f``)."""
    from scipy.integrate._ivp import dop853_coefficients as d

    n = d.N_STAGES
    return (np.ascontiguousarray(d.A[:n, :n]), np.ascontiguousarray(d.B), np.ascontiguousarray(d.C[:n]),
            np.ascontiguousarray(d.E3), np.ascontiguousarray(d.E5))


@njit(cache=True)
def _rms_scaled(x, scale):  # pragma: no cover - compiled
    s = 0.0
    for j in range(x.shape[0]):
        s += (x[j] / scale[j]) ** 2
    return math.sqrt(s) / math.sqrt(x.shape[0])


@njit(cache=True)
def dop853_span(y, T, rtol, atol, P, force, torque, burn, thr, wind, trans, A, B, C, E3, E5, stats):  # pragma: no cover - compiled
    """Advance ``y`` in place from 0 to ``T`` [s] with DOP853 exactly as scipy's ``solve_ivp`` steps it
    (initial step of ``select_initial_step`` with order 7, ``SAFETY = 0.9``, factors in [0.2, 10],
    exponent -1/8, no growth right after a rejection). ``stats`` gets ``[accepted, rejected,
    evaluations]`` added. Returns 0, or -1 if the step became too small (scipy's failure)."""
    ns = 12
    K = np.empty((ns + 1, 14))
    f = np.empty(14)
    y1 = np.empty(14)
    f1 = np.empty(14)
    scale = np.empty(14)
    ynew = np.empty(14)
    tmp = np.empty(14)
    acc = np.empty(6)
    derivative(y, P, force, torque, burn, thr, wind, trans, f, acc)
    ev = 1
    # select_initial_step (HNW II.4), order = error estimator order 7.
    for j in range(14):
        scale[j] = atol + abs(y[j]) * rtol
    d0 = _rms_scaled(y, scale)
    d1 = _rms_scaled(f, scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, T)
    for j in range(14):
        y1[j] = y[j] + h0 * f[j]
    derivative(y1, P, force, torque, burn, thr, wind, trans, f1, acc)
    ev += 1
    for j in range(14):
        tmp[j] = f1[j] - f[j]
    d2 = _rms_scaled(tmp, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    h_abs = min(100.0 * h0, h1, T)
    t = 0.0
    while t < T:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:  # noqa: PLR1730 - scipy's test, word for word
            h_abs = min_step
        accepted = False
        rejected = False
        while not accepted:
            if h_abs < min_step:
                stats[2] += ev
                return -1
            t_new = t + h_abs
            if t_new - T > 0.0:
                t_new = T
            h = t_new - t
            h_abs = abs(h)
            for j in range(14):
                K[0, j] = f[j]
            for s in range(1, ns):
                for j in range(14):
                    dy = 0.0
                    for m in range(s):
                        dy += K[m, j] * A[s, m]
                    tmp[j] = y[j] + dy * h
                derivative(tmp, P, force, torque, burn, thr, wind, trans, K[s], acc)
                ev += 1
            for j in range(14):
                dy = 0.0
                for m in range(ns):
                    dy += K[m, j] * B[m]
                ynew[j] = y[j] + h * dy
            derivative(ynew, P, force, torque, burn, thr, wind, trans, K[ns], acc)
            ev += 1
            e5 = 0.0
            e3 = 0.0
            for j in range(14):
                sc = atol + max(abs(y[j]), abs(ynew[j])) * rtol
                a5 = 0.0
                a3 = 0.0
                for m in range(ns + 1):
                    a5 += K[m, j] * E5[m]
                    a3 += K[m, j] * E3[m]
                e5 += (a5 / sc) ** 2
                e3 += (a3 / sc) ** 2
            if e5 == 0.0 and e3 == 0.0:
                err = 0.0
            else:
                err = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * 14.0)
            if err < 1.0:
                factor = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
                stats[0] += 1
            else:
                h_abs *= max(0.2, 0.9 * err ** (-1.0 / 8.0))
                rejected = True
                stats[1] += 1
        t = t_new
        for j in range(14):
            y[j] = ynew[j]
            f[j] = K[ns, j]
    stats[2] += ev
    return 0


@njit(cache=True)
def _inertia(P, fuel, out):  # pragma: no cover - compiled
    """Principal moments [kg m^2] as ``Vehicle.inertia``: fixed, or mass times the gyration radii squared."""
    if P[_k.P_FIXED_I] != 0.0:
        out[0], out[1], out[2] = P[_k.P_K1], P[_k.P_K2], P[_k.P_K3]
    else:
        m = P[_k.P_DRY] + fuel
        out[0], out[1], out[2] = m * P[_k.P_K1], m * P[_k.P_K2], m * P[_k.P_K3]


@njit(cache=True)
def _torque_part(acc, w0, w1, w2, I, out):  # pragma: no cover - compiled
    """``I^-1 Q = omega' - I^-1 (I w x w)`` (as ``geometric._torque_part``)."""
    u0, u1, u2 = I[0] * w0, I[1] * w1, I[2] * w2
    out[0] = acc[3] - (u1 * w2 - u2 * w1) / I[0]
    out[1] = acc[4] - (u2 * w0 - u0 * w2) / I[1]
    out[2] = acc[5] - (u0 * w1 - u1 * w0) / I[2]


def _make_geometric_steps():
    from lander_sim.integrators.free_rotor import free_rotor_step

    rotor = njit(cache=True)(free_rotor_step)

    @njit(cache=True)
    def geometric_steps(y, dt, n, P, force, torque, burn, thr, wind, trans, renormalise):  # pragma: no cover - compiled
        """``n`` steps of :class:`~lander_sim.integrators.geometric.Geometric` (kick, DLM drift, kick) in place."""
        a0 = np.empty(6)
        a1 = np.empty(6)
        est = np.empty(14)
        I0 = np.empty(3)
        I1 = np.empty(3)
        tau0 = np.empty(3)
        tau1 = np.empty(3)
        h = 0.5 * dt
        for _ in range(n):
            _inertia(P, y[13], I0)
            _k._accelerations(y, P, force, torque, thr, wind, a0)
            rate = 0.0
            if P[_k.P_THRUST] != 0.0 and y[13] > 0.0:
                for i in range(thr.shape[0]):
                    rate += thr[i] * burn[i]
                rate = -rate
            _torque_part(a0, y[10], y[11], y[12], I0, tau0)
            wh0, wh1, wh2 = y[10] + h * tau0[0], y[11] + h * tau0[1], y[12] + h * tau0[2]
            vh0 = vh1 = vh2 = 0.0
            if trans != 0.0:
                vh0, vh1, vh2 = y[3] + h * a0[0], y[4] + h * a0[1], y[5] + h * a0[2]
                y[0] += dt * vh0
                y[1] += dt * vh1
                y[2] += dt * vh2
            s, x, qy, z, L1, L2, L3 = rotor(y[6], y[7], y[8], y[9], I0[0] * wh0, I0[1] * wh1, I0[2] * wh2,
                                            I0[0], I0[1], I0[2], dt)
            y[6], y[7], y[8], y[9] = s, x, qy, z
            if renormalise:
                _renormalise(y)
            wd0, wd1, wd2 = L1 / I0[0], L2 / I0[1], L3 / I0[2]
            y[13] += rate * dt
            if y[13] < 0.0:  # noqa: PLR1730 - as clamp_fuel: a NaN stays NaN (max() would hide it)
                y[13] = 0.0
            for j in range(14):
                est[j] = y[j]
            est[10], est[11], est[12] = wd0 + h * tau0[0], wd1 + h * tau0[1], wd2 + h * tau0[2]
            if trans != 0.0:
                est[3], est[4], est[5] = vh0 + h * a0[0], vh1 + h * a0[1], vh2 + h * a0[2]
            _k._accelerations(est, P, force, torque, thr, wind, a1)
            _inertia(P, y[13], I1)
            _torque_part(a1, est[10], est[11], est[12], I1, tau1)
            y[10], y[11], y[12] = wd0 + h * tau1[0], wd1 + h * tau1[1], wd2 + h * tau1[2]
            if trans != 0.0:
                y[3], y[4], y[5] = vh0 + h * a1[0], vh1 + h * a1[1], vh2 + h * a1[2]
        return 2 * n

    return geometric_steps


_GEOMETRIC = None


def geometric_steps(*args: Any) -> int:
    """``n`` compiled steps of the geometric splitting (built on first use: it compiles
    :func:`lander_sim.integrators.free_rotor.free_rotor_step` itself). Arguments as
    :func:`rk4_steps`; quaternion mode only: raises ``ValueError`` for Euler-angle parameters."""
    global _GEOMETRIC
    if args[3][_k.P_EULER] != 0.0:
        # The DLM drift moves q by exact principal-axis rotations (the exponential map); the ZXZ
        # angles have no such flow, and reading them as a quaternion would fly garbage silently.
        raise ValueError("geometric splitting is quaternion-only: its attitude update is the exponential map of q")
    if _GEOMETRIC is None:
        _GEOMETRIC = _make_geometric_steps()
    return _GEOMETRIC(*args)
