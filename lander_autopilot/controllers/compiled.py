"""Compiled form of the linear state-feedback laws: the same law as a typed description + a numba kernel.

The Python ``update()`` of each law stays the reference; this module describes a law by its
*kind* and its gains (:class:`CompiledLaw`) so that the same arithmetic runs inside a compiled
loop (:mod:`lander_tools.sweep.batched_kernel`) with no Python call per control step. The laws
covered, all ``u = u_altitude + u_attitude`` then clipped (control reference, seed 2 section 4.2):

* altitude state feedback, eq 18-19: ``u_alt = m / T_v (G M / r^2 - k_z (h - h_d) - k_zd h')``
  (``altitude``, ``altitude-p``, ``lqr``'s altitude part), and its integral-action variant
  (``altitude-integral``: state ``[int (h - h_d) dt, h - h_d, h']``, conditional integration);
* attitude state feedback ``u_att = -s K e``: Euler angles, eq 28 (``e = [E - E_d wrapped,
  omega - omega_d]``), or quaternion (``e = [2 v_err, omega - omega_d]``, ``q_err = q_d* q``);
* the summed laws (``combined``, ``combined-quaternion``, ``integral``, ``lqr``) with the
  attitude-priority mixing of :class:`~.combined.SumController`.

A controller offers its description through ``compiled_form()`` (None when it, or a subclass that
overrides the law, has none); :func:`compiled_form` asks any object, so a third-party plug-in
without one simply flies on the per-flight path. The description is packed into two float arrays
(:meth:`CompiledLaw.pack`) for the kernel :func:`law_update`; :func:`reference_update` runs the
kernel from Python for tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from lander_sim.fast.lander_kernel import njit  # type: ignore[attr-defined]  # numba's, as the kernels use it
from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.rotation import euler_to_quat, quat_conj

__all__ = [
    "N_DEMAND",
    "N_LAW_STATE",
    "AltitudeLaw",
    "AttitudeLaw",
    "CompiledLaw",
    "LawState",
    "compiled_form",
    "demand_array",
    "keeps_law",
    "law_update",
    "reference_update",
]


class AltitudeLaw(IntEnum):
    """Collective (altitude) part of a law."""

    NONE = 0
    STATE_FEEDBACK = 1  #: eq 18 with gains as accelerations ``(k_z, k_zd)`` = ``B K`` of eq 19
    INTEGRAL = 2  #: ``(k_i, k_z, k_zd)`` with conditional integration (anti-windup)


class AttitudeLaw(IntEnum):
    """Differential (attitude) part of a law."""

    NONE = 0
    EULER = 1  #: eq 28, ZXZ angle errors wrapped to [-pi, pi]
    QUATERNION = 2  #: ``[2 v_err, omega - omega_d]``


@dataclass(frozen=True)
class CompiledLaw:
    """A linear state-feedback law as data (SI units; body-frame rates, world-frame position).

    Attributes
    ----------
    altitude, attitude : AltitudeLaw, AttitudeLaw
        Which parts the law has.
    n_thrusters : int
    dry_mass : float
        Dry mass of the vehicle the law was designed on [kg]: the law's mass model is ``dry + fuel``.
    T_v : float
        Vertical thrust of all thrusters at full throttle, eq 16 [N].
    k_altitude : ndarray (3,)
        Altitude gains as accelerations: ``(k_z, k_zd, 0)`` [1/s^2, 1/s] or ``(k_i, k_z, k_zd)``.
    K_attitude : ndarray (N, 6)
        Attitude gain (zeros without an attitude part).
    attitude_design_mass : float
        Mass the attitude gain was designed at [kg] (``s = m / m_d``).
    attitude_mass_scaled : bool
        ``s = m / m_d`` (inertia scales with mass) or ``s = 1`` (fixed inertia).
    summed : bool
        Output as :meth:`SumController.update` (mixing counts as saturation) rather than plain clipping.
    attitude_priority : bool
        Summed laws: give up collective throttle before differential throttle.
    """

    altitude: AltitudeLaw
    attitude: AttitudeLaw
    n_thrusters: int
    dry_mass: float
    T_v: float = 0.0
    k_altitude: np.ndarray = field(default_factory=lambda: np.zeros(3))
    K_attitude: np.ndarray | None = None
    attitude_design_mass: float = 1.0
    attitude_mass_scaled: bool = False
    summed: bool = False
    attitude_priority: bool = False

    def pack(self) -> tuple[np.ndarray, np.ndarray]:
        """``(params, K)`` for :func:`law_update`: ``params`` holds the scalars (layout ``L_*``)."""
        p = np.zeros(N_LAW_PARAMS)
        p[L_ALT] = int(self.altitude)
        p[L_ATT] = int(self.attitude)
        p[L_SUMMED] = float(self.summed)
        p[L_PRIORITY] = float(self.attitude_priority)
        p[L_DRY] = self.dry_mass
        p[L_TV] = self.T_v
        p[L_K0:L_K0 + 3] = self.k_altitude
        p[L_ATT_MASS] = self.attitude_design_mass
        p[L_ATT_SCALED] = float(self.attitude_mass_scaled)
        K = np.zeros((self.n_thrusters, 6)) if self.K_attitude is None else self.K_attitude
        return p, np.ascontiguousarray(K, dtype=float)

    @staticmethod
    def combine(altitude: CompiledLaw, attitude: CompiledLaw, attitude_priority: bool) -> CompiledLaw:
        """The summed law of an altitude-only and an attitude-only description."""
        return CompiledLaw(
            altitude=altitude.altitude, attitude=attitude.attitude, n_thrusters=altitude.n_thrusters,
            dry_mass=altitude.dry_mass, T_v=altitude.T_v, k_altitude=altitude.k_altitude,
            K_attitude=attitude.K_attitude, attitude_design_mass=attitude.attitude_design_mass,
            attitude_mass_scaled=attitude.attitude_mass_scaled, summed=True, attitude_priority=attitude_priority,
        )


# Layout of the packed law parameters.
L_ALT, L_ATT, L_SUMMED, L_PRIORITY, L_DRY, L_TV, L_K0, L_K1, L_K2, L_ATT_MASS, L_ATT_SCALED = range(11)
N_LAW_PARAMS = 11
# Layout of the demand array: altitude [m], ZXZ attitude [rad], omega_d (body) [rad/s], q_d* (4).
D_ALT, D_E0, D_W0, D_QC0 = 0, 1, 4, 7
N_DEMAND = 11
# Layout of the law's own state: integral [m s], time of the last update [s], has-last flag.
S_INTEGRAL, S_T_LAST, S_HAS_LAST = range(3)
N_LAW_STATE = 3


@dataclass
class LawState:
    """The mutable state of one flight's law (the integral of the integral law), for :func:`reference_update`."""

    values: np.ndarray = field(default_factory=lambda: np.zeros(N_LAW_STATE))

    def reset(self) -> None:
        self.values[:] = 0.0


def compiled_form(controller: Any) -> CompiledLaw | None:
    """The controller's :class:`CompiledLaw`, or None (a plug-in without one flies per flight)."""
    get = getattr(controller, "compiled_form", None)
    if get is None:
        return None
    try:
        return get()
    except Exception:  # noqa: BLE001 - a broken description means "no compiled form", never a crash
        return None


def keeps_law(obj: Any, base: type, *names: str) -> bool:
    """True if ``obj``'s class uses ``base``'s own ``names`` (a subclass that overrides the law has no compiled form)."""
    cls = type(obj)
    return all(getattr(cls, n) is getattr(base, n) for n in names)


def demand_array(altitude: float, attitude: tuple[float, float, float], omega_B: tuple[float, float, float]) -> np.ndarray:
    """A :class:`~.base.Demand` packed for :func:`law_update` (``q_d*`` computed once, as the quaternion law caches it)."""
    d = np.zeros(N_DEMAND)
    d[D_ALT] = altitude
    d[D_E0:D_E0 + 3] = attitude
    d[D_W0:D_W0 + 3] = omega_B
    d[D_QC0:D_QC0 + 4] = quat_conj(euler_to_quat(np.asarray(attitude, dtype=float)))
    return d


_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def _wrap(a):  # pragma: no cover - compiled
    """``math.remainder(a, 2 pi)`` (numba has no remainder): exact for the small multiples met here (Sterbenz)."""
    n = np.rint(a / _TWO_PI)
    return a - n * _TWO_PI


@njit(cache=True)
def quat_to_euler_zxz(s, a, b, c):  # pragma: no cover - compiled
    """ZXZ angles ``(phi, theta, psi)`` of a unit quaternion (as ``rotation.quat_to_euler``: eq 13,
    then the inverse of eq 3), returned as scalars so the law keeps them in registers."""
    r00 = s * s + a * a - b * b - c * c
    r01 = 2.0 * (a * b + s * c)
    r02 = 2.0 * (a * c - s * b)
    r12 = 2.0 * (s * a + b * c)
    r20 = 2.0 * (s * b + a * c)
    r21 = 2.0 * (b * c - s * a)
    r22 = s * s - a * a - b * b + c * c
    st = math.hypot(r20, r21)
    theta = math.atan2(st, r22)
    if st > 1e-12:
        return math.atan2(r20, -r21), theta, math.atan2(r02, r12)
    return math.atan2(r01, r00), theta, 0.0


@njit(cache=True)
def law_update(params, K, law_state, t, y, demand, u, e):  # pragma: no cover - compiled
    """Throttles of the law into ``u`` (N,) for flat state ``y`` at time ``t`` [s]; returns ``saturated``.

    The same arithmetic, in the same order, as the Python ``update()`` of the law described by
    ``params``/``K`` (:meth:`CompiledLaw.pack`); ``law_state`` (``S_*``) is updated as the law's
    own state; ``e`` is a (6,) scratch buffer.
    """
    n = u.shape[0]
    x, yy, z = y[0], y[1], y[2]
    r = math.sqrt(x * x + yy * yy + z * z)
    h = r - MARS_RADIUS
    hd = (y[3] * x + y[4] * yy + y[5] * z) / r
    fuel = y[13]
    alt_kind = int(params[L_ALT])
    u_alt = 0.0
    if alt_kind != 0:
        m = params[L_DRY] + fuel
        rr = h + MARS_RADIUS
        if alt_kind == 1:
            acc = GM_MARS / (rr * rr) - params[L_K0] * (h - demand[D_ALT]) - params[L_K1] * hd
            u_alt = m / params[L_TV] * acc
        else:
            err = h - demand[D_ALT]
            u_alt = m / params[L_TV] * (
                GM_MARS / (rr * rr) - params[L_K0] * law_state[S_INTEGRAL] - params[L_K1] * err - params[L_K2] * hd
            )
            if law_state[S_HAS_LAST] != 0.0:
                dt = t - law_state[S_T_LAST]
                if dt > 0.0 and not ((u_alt >= 1.0 and err < 0.0) or (u_alt <= 0.0 and err > 0.0)):
                    law_state[S_INTEGRAL] += err * dt
            law_state[S_T_LAST] = t
            law_state[S_HAS_LAST] = 1.0
    for i in range(n):
        u[i] = u_alt
    att_kind = int(params[L_ATT])
    if att_kind != 0:
        if att_kind == 1:
            phi, theta, psi = quat_to_euler_zxz(y[6], y[7], y[8], y[9])
            e0 = _wrap(phi - demand[D_E0])
            e1 = theta - demand[D_E0 + 1]
            e2 = _wrap(psi - demand[D_E0 + 2])
        else:
            c0, c1, c2, c3 = demand[D_QC0], demand[D_QC0 + 1], demand[D_QC0 + 2], demand[D_QC0 + 3]
            s2, x2, y2, z2 = y[6], y[7], y[8], y[9]
            qs = c0 * s2 - c1 * x2 - c2 * y2 - c3 * z2
            qx = c0 * x2 + s2 * c1 + c2 * z2 - c3 * y2
            qy = c0 * y2 + s2 * c2 + c3 * x2 - c1 * z2
            qz = c0 * z2 + s2 * c3 + c1 * y2 - c2 * x2
            k = 2.0 if qs >= 0.0 else -2.0
            e0 = k * qx
            e1 = k * qy
            e2 = k * qz
        # The error vector in registers (a tuple): ``e`` stays untouched scratch.
        ev = (e0, e1, e2, y[10] - demand[D_W0], y[11] - demand[D_W0 + 1], y[12] - demand[D_W0 + 2])
        scale = (params[L_DRY] + fuel) / params[L_ATT_MASS] if params[L_ATT_SCALED] != 0.0 else 1.0
        for i in range(n):
            acc = 0.0
            for j in range(6):
                acc += K[i, j] * ev[j]
            u[i] = u[i] + (-scale) * acc
    mixed = False
    lo = u[0]
    hi = u[0]
    for i in range(1, n):
        lo = min(lo, u[i])
        hi = max(hi, u[i])
    if params[L_SUMMED] != 0.0 and params[L_PRIORITY] != 0.0 and not (lo >= 0.0 and hi <= 1.0):
        # SumController.mixed_command: keep the differential part, move the collective into range.
        c = u_alt  # mean of the collective throttles, summed in numpy's order (they are equal)
        for _ in range(1, n):
            c += u_alt
        c = c / n
        dlo = lo - c
        dhi = hi - c
        span = dhi - dlo
        shrink = span > 1.0
        if shrink:
            dlo, dhi = dlo / span, dhi / span
        c_fit = min(max(c, -dlo), 1.0 - dhi)
        for i in range(n):
            d = u[i] - c
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
    return mixed or lo < -1e-9 or hi > 1.0 + 1e-9


def reference_update(law: CompiledLaw, state: LawState, t: float, y: np.ndarray, demand: np.ndarray) -> tuple[np.ndarray, bool]:
    """Run :func:`law_update` once from Python: ``(throttles, saturated)`` (for tests and tools)."""
    params, K = law.pack()
    u = np.zeros(law.n_thrusters)
    sat = law_update(params, K, state.values, float(t), np.ascontiguousarray(y, dtype=float), demand, u, np.zeros(6))
    return u, bool(sat)
