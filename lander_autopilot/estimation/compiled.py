"""The navigation filter with its covariance arithmetic compiled (numba): the same filter, faster.

:class:`CompiledNavFilter` is :class:`~.ekf.NavFilter` (same state, same input checks, the same
nominal-state arithmetic to the bit) with the two 15 x 15 covariance steps, which are most of the
Python filter's time, done by numba kernels:

* propagation, :func:`covariance_propagate`: ``P <- Phi P Phi^T + Q_d`` with
  ``Phi = I + F dt + (F dt)^2 / 2`` and ``Q_d = G_n Q_c G_n^T dt`` (the error dynamics of
  :mod:`.ekf`, Sola 2017 eq 237), then symmetrised;
* the sequential scalar updates, :func:`sequential_update`: for each component ``i`` of a
  measurement with diagonal ``R``, ``y_i' = y_i - h_i dx``, ``s = h P h^T + r_i``, ``k = P h^T / s``,
  ``dx += k y_i'`` and the Joseph form ``(I - k h) P (I - k h)^T + r_i k k^T`` expanded with
  ``P h^T = s k``, ``P - k (P h^T)^T - (P h^T) k^T + s k k^T`` (O(n^2) for a scalar, the same
  matrix in exact arithmetic; Bierman 1977).

The kernels sum in another order than numpy's BLAS products, so the filter agrees with the Python
one to rounding, not to the bit (test/estimation/test_compiled_filter.py: after 300 random steps the
largest relative difference is 1.5e-12, in the gyro bias; the test allows 1e-9). Without numba the kernels run as
plain Python (the same arithmetic, slowly).

For loops compiled whole (the batched sweep core, :mod:`lander_tools.sweep.batched_kernel`) the
filter's every step is a kernel too: :func:`nav_propagate` and the ``nav_update_*`` functions work on
a packed state ``x`` and ``P`` (:func:`pack_filter`) with the nominal-state arithmetic of
:class:`CompiledNavFilter` written element by element and its two covariance kernels.
"""
from __future__ import annotations

import math

import numpy as np

import lander_sim.fast.quaternion as _quaternion
from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import HAVE_NUMBA, njit  # type: ignore[attr-defined]
from lander_sim.fast.quaternion import qmul, rotation_into
from lander_sim.physics.rotation import quat_exp_step, quat_mult, quat_normalise, quat_to_matrix

from .ekf import DBA, DBG, DR, DTH, DV, N_ERR, NavFilter, NavState, Update, small_rotation

# The kernels call the quaternion kernels of that module: recompile when it changes.
invalidate_if_changed(__file__, _quaternion.__file__)

__all__ = ["HAVE_NUMBA", "N_ERR", "N_X", "CompiledNavFilter", "compiled_copy", "covariance_propagate", "nav_propagate",
           "nav_update_altimeter", "nav_update_doppler", "nav_update_ground_fix", "nav_update_star_tracker",
           "pack_filter", "sequential_update"]


@njit(cache=True)
def covariance_propagate(P, C, f, w, gg, dt, qc):
    """``Phi P Phi^T + Q_d`` symmetrised (module docstring). ``C``: body -> world (3 x 3); ``f``,
    ``w``: bias-corrected specific force [m/s^2] and body rate [rad/s]; ``gg``: the gravity gradient
    (3 x 3) [1/s^2]; ``dt`` [s]; ``qc`` (12): the continuous noise densities squared."""
    n = 15
    F = np.zeros((n, n))
    for i in range(3):
        F[i, 3 + i] = 1.0
        F[6 + i, 9 + i] = -1.0
        for j in range(3):
            F[3 + i, j] = gg[i, j]
            F[3 + i, 12 + j] = -C[i, j]
    # -C [f x]: column j of [f x] is f x e_j
    sk_f = np.array([[0.0, -f[2], f[1]], [f[2], 0.0, -f[0]], [-f[1], f[0], 0.0]])
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for m in range(3):
                acc += C[i, m] * sk_f[m, j]
            F[3 + i, 6 + j] = -acc
    F[6, 7] = w[2]
    F[6, 8] = -w[1]
    F[7, 6] = -w[2]
    F[7, 8] = w[0]
    F[8, 6] = w[1]
    F[8, 7] = -w[0]
    Fd = F * dt
    Phi = np.eye(n) + Fd + 0.5 * (Fd @ Fd)
    Gn = np.zeros((n, 12))
    for i in range(3):
        for j in range(3):
            Gn[3 + i, 3 + j] = -C[i, j]
        Gn[6 + i, i] = -1.0
        Gn[9 + i, 6 + i] = 1.0
        Gn[12 + i, 9 + i] = 1.0
    Qd = ((Gn * qc) @ Gn.T) * dt
    out = Phi @ P @ Phi.T + Qd
    return 0.5 * (out + out.T)


@njit(cache=True)
def sequential_update(P, H, y, var):
    """The scalar updates of one measurement (module docstring): ``(dx, P)`` after them all, ``P``
    symmetrised. ``H`` (m x 15), innovation ``y`` (m), noise variances ``var`` (m)."""
    n = P.shape[0]
    P = P.copy()
    dx = np.zeros(n)
    for i in range(y.shape[0]):
        h = H[i]
        yi = y[i] - h @ dx
        Ph = P @ h
        si = h @ Ph + var[i]
        k = Ph / si
        dx = dx + k * yi
        for a in range(n):
            for b in range(n):
                P[a, b] = P[a, b] - k[a] * Ph[b] - Ph[a] * k[b] + si * k[a] * k[b]
    return dx, 0.5 * (P + P.T)


class CompiledNavFilter(NavFilter):
    """:class:`~.ekf.NavFilter` with the covariance steps compiled (module docstring)."""

    def propagate(self, omega_m: np.ndarray, f_m: np.ndarray, dt: float) -> None:
        w_m, f_m = self._vec("imu", omega_m, 3), self._vec("imu", f_m, 3)
        if not (math.isfinite(dt) and dt > 0.0):
            self._reject("imu", f"dt must be a finite number > 0 s, got {dt!r}")
        s = self.state
        w = w_m - s.b_g
        f = f_m - s.b_a
        C = quat_to_matrix(s.q).T
        r2 = float(s.r_W @ s.r_W)
        g = -self.gm * s.r_W / (r2 * math.sqrt(r2))
        a = C @ f + g
        rhat = s.r_W / math.sqrt(r2)
        gg = self.gm * (3.0 * np.outer(rhat, rhat) - np.eye(3)) / (r2 * math.sqrt(r2))
        n = self.noise
        qc = np.repeat([n.gyro_noise_density**2, n.accel_noise_density**2, n.gyro_bias_walk**2, n.accel_bias_walk**2], 3)
        s.r_W = s.r_W + s.v_W * dt + 0.5 * a * dt * dt
        s.v_W = s.v_W + a * dt
        s.q = quat_normalise(quat_exp_step(s.q, w, dt))
        s.P = covariance_propagate(s.P, np.ascontiguousarray(C), f, w, gg, float(dt), qc)
        s.t += dt

    def _update(self, key: str, y: np.ndarray, H: np.ndarray, sigma: np.ndarray) -> Update:
        s = self.state
        S = H @ s.P @ H.T + np.diag(sigma**2)
        nis = float(y @ np.linalg.solve(S, y))
        dx, P = sequential_update(s.P, np.ascontiguousarray(H, dtype=float), np.asarray(y, float), sigma**2)
        s.r_W = s.r_W + dx[DR]
        s.v_W = s.v_W + dx[DV]
        s.q = quat_normalise(quat_mult(s.q, small_rotation(dx[DTH])))
        s.b_g = s.b_g + dx[DBG]
        s.b_a = s.b_a + dx[DBA]
        s.P = P
        return Update(key, y, S, nis)


def compiled_copy(filt: NavFilter) -> CompiledNavFilter:
    """A :class:`CompiledNavFilter` with ``filt``'s state (copied), noise, gravity and counts."""
    s = filt.state
    state = NavState(r_W=s.r_W.copy(), v_W=s.v_W.copy(), q=s.q.copy(), b_g=s.b_g.copy(), b_a=s.b_a.copy(),
                     P=np.array(s.P, float), t=s.t)
    assert state.P.shape == (N_ERR, N_ERR)
    return CompiledNavFilter(state, filt.noise, gm=filt.gm, planet_radius=filt.planet_radius,
                             rejected=dict(filt.rejected))


# --- the whole filter as kernels, for compiled loops -------------------------------------------
#
# The filter's state packed as ``x`` (16): ``r_W`` (3), ``v_W`` (3), ``q`` (4), ``b_g`` (3), ``b_a``
# (3), with ``P`` (15 x 15) beside it; the same steps as :class:`CompiledNavFilter` (its nominal
# arithmetic element by element, its covariance steps the kernels above), so a compiled loop that
# flies many flights keeps the filter inside it. Each returns False where the filter would refuse
# its input (:class:`~.ekf.EstimationError`: not finite, a noise not > 0, a quaternion not unit) or
# not use it (the altimeter's predicted beam missing the planet), the state then unchanged.

#: Slots of the packed state ``x``.
X_R, X_V, X_Q, X_BG, X_BA = 0, 3, 6, 10, 13
N_X = 16


@njit(cache=True)
def _set_q_normalised(x, q0, q1, q2, q3):  # pragma: no cover - compiled
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3] = q0 / n, q1 / n, q2 / n, q3 / n


@njit(cache=True)
def nav_propagate(x, P, omega_m, f_m, dt, gm, qc):  # pragma: no cover - compiled
    """:meth:`CompiledNavFilter.propagate` on ``x``, ``P`` (``gm`` [m^3/s^2], ``qc`` (12) the noise
    densities squared)."""
    for j in range(3):
        if not (math.isfinite(omega_m[j]) and math.isfinite(f_m[j])):
            return False
    if not (math.isfinite(dt) and dt > 0.0):
        return False
    w = np.empty(3)
    f = np.empty(3)
    for j in range(3):
        w[j] = omega_m[j] - x[X_BG + j]
        f[j] = f_m[j] - x[X_BA + j]
    R = np.empty((3, 3))
    rotation_into(x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3], R)
    C = np.ascontiguousarray(R.T)
    r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2]
    c3 = r2 * math.sqrt(r2)
    rn = math.sqrt(r2)
    a = np.empty(3)
    for i in range(3):
        a[i] = (C[i, 0] * f[0] + C[i, 1] * f[1] + C[i, 2] * f[2]) + -gm * x[i] / c3
    gg = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            gg[i, j] = gm * (3.0 * ((x[i] / rn) * (x[j] / rn)) - (1.0 if i == j else 0.0)) / c3
    for j in range(3):
        x[X_R + j] = x[X_R + j] + x[X_V + j] * dt + 0.5 * a[j] * dt * dt
        x[X_V + j] = x[X_V + j] + a[j] * dt
    # quat_exp_step, then normalised
    wn = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    h = 0.5 * wn * dt
    if wn * dt < 1e-8:
        k = 0.5 * dt * (1.0 - h * h / 6.0)
    else:
        k = math.sin(h) / wn
    q0, q1, q2, q3 = qmul(x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3], math.cos(h), k * w[0], k * w[1], k * w[2])
    _set_q_normalised(x, q0, q1, q2, q3)
    P[:, :] = covariance_propagate(P, C, f, w, gg, dt, qc)
    return True


@njit(cache=True)
def _apply(x, P, H, y, sigma):  # pragma: no cover - compiled
    """The scalar updates (:func:`sequential_update`) and the injection of ``dx`` into ``x``."""
    m = y.shape[0]
    for i in range(m):
        if not (math.isfinite(y[i]) and math.isfinite(sigma[i]) and sigma[i] > 0.0):
            return False
    dx, Pn = sequential_update(P, H, y, sigma * sigma)
    P[:, :] = Pn
    for j in range(3):
        x[X_R + j] = x[X_R + j] + dx[j]
        x[X_V + j] = x[X_V + j] + dx[3 + j]
    th0, th1, th2 = dx[6], dx[7], dx[8]
    a = math.sqrt(th0 * th0 + th1 * th1 + th2 * th2)
    if a < 1e-12:  # small_rotation's normalised first order
        n = math.sqrt(1.0 + (0.5 * th0) * (0.5 * th0) + (0.5 * th1) * (0.5 * th1) + (0.5 * th2) * (0.5 * th2))
        e0, e1, e2, e3 = 1.0 / n, 0.5 * th0 / n, 0.5 * th1 / n, 0.5 * th2 / n
    else:
        k = math.sin(0.5 * a) / a
        e0, e1, e2, e3 = math.cos(0.5 * a), k * th0, k * th1, k * th2
    q0, q1, q2, q3 = qmul(x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3], e0, e1, e2, e3)
    _set_q_normalised(x, q0, q1, q2, q3)
    for j in range(3):
        x[X_BG + j] = x[X_BG + j] + dx[9 + j]
        x[X_BA + j] = x[X_BA + j] + dx[12 + j]
    return True


@njit(cache=True)
def nav_update_star_tracker(x, P, q_m, sigma):  # pragma: no cover - compiled
    """:meth:`~.ekf.NavFilter.update_star_tracker`: ``y = 2 vec(q^* x q_m)`` (the shorter way), ``H = [0, 0, I, 0, 0]``."""
    nq = math.sqrt(q_m[0] * q_m[0] + q_m[1] * q_m[1] + q_m[2] * q_m[2] + q_m[3] * q_m[3])
    if not math.isfinite(nq) or abs(nq - 1.0) > 1e-6:
        return False
    d0, d1, d2, d3 = qmul(x[X_Q], -x[X_Q + 1], -x[X_Q + 2], -x[X_Q + 3], q_m[0], q_m[1], q_m[2], q_m[3])
    if d0 < 0.0:
        d0, d1, d2, d3 = -d0, -d1, -d2, -d3
    n = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
    k = 2.0 if n < 1e-15 else 2.0 * math.atan2(n, d0) / n
    y = np.array([k * d1, k * d2, k * d3])
    H = np.zeros((3, N_ERR))
    for i in range(3):
        H[i, 6 + i] = 1.0
    return _apply(x, P, H, y, sigma[0:3].copy())


@njit(cache=True)
def nav_update_altimeter(x, P, rho_m, sigma, beam_B, planet_radius):  # pragma: no cover - compiled
    """:meth:`~.ekf.NavFilter.update_altimeter` (slant range along ``beam_B`` to the sphere of ``planet_radius``)."""
    R = np.empty((3, 3))
    rotation_into(x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3], R)
    nb = math.sqrt(beam_B[0] * beam_B[0] + beam_B[1] * beam_B[1] + beam_B[2] * beam_B[2])
    dB = np.array([beam_B[0] / nb, beam_B[1] / nb, beam_B[2] / nb])
    d = np.empty(3)
    for i in range(3):  # C d_B, C = R^T
        d[i] = R[0, i] * dB[0] + R[1, i] * dB[1] + R[2, i] * dB[2]
    rd = x[0] * d[0] + x[1] * d[1] + x[2] * d[2]
    disc = rd * rd - ((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) - planet_radius * planet_radius)
    if not (math.isfinite(rho_m) and math.isfinite(sigma) and sigma > 0.0):
        return False
    if disc < 0.0:
        return False
    s = -rd - math.sqrt(disc)
    if s < 0.0:
        return False
    p = np.empty(3)
    for j in range(3):
        p[j] = x[j] + s * d[j]
    pd = p[0] * d[0] + p[1] * d[1] + p[2] * d[2]
    H = np.zeros((1, N_ERR))
    pc = np.empty(3)  # p^T C
    for j in range(3):
        pc[j] = p[0] * R[j, 0] + p[1] * R[j, 1] + p[2] * R[j, 2]
    # (p^T C) [d_B x]: column j of [d_B x] is d_B x e_j
    sk = (pc[1] * dB[2] - pc[2] * dB[1], pc[2] * dB[0] - pc[0] * dB[2], pc[0] * dB[1] - pc[1] * dB[0])
    for j in range(3):
        H[0, j] = -p[j] / pd
        H[0, 6 + j] = s * sk[j] / pd
    return _apply(x, P, H, np.array([rho_m - s]), np.array([sigma]))


@njit(cache=True)
def nav_update_doppler(x, P, v_m, sigma):  # pragma: no cover - compiled
    """:meth:`~.ekf.NavFilter.update_doppler`: ``z = R v``, ``H_v = R``, ``H_th = [(R v) x]``."""
    R = np.empty((3, 3))
    rotation_into(x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3], R)
    vb = np.empty(3)
    for i in range(3):
        vb[i] = R[i, 0] * x[X_V] + R[i, 1] * x[X_V + 1] + R[i, 2] * x[X_V + 2]
    H = np.zeros((3, N_ERR))
    for i in range(3):
        for j in range(3):
            H[i, 3 + j] = R[i, j]
    H[0, 7], H[0, 8] = -vb[2], vb[1]
    H[1, 6], H[1, 8] = vb[2], -vb[0]
    H[2, 6], H[2, 7] = -vb[1], vb[0]
    y = np.array([v_m[0] - vb[0], v_m[1] - vb[1], v_m[2] - vb[2]])
    return _apply(x, P, H, y, sigma[0:3].copy())


@njit(cache=True)
def nav_update_ground_fix(x, P, z, sigma):  # pragma: no cover - compiled
    """:meth:`~.ekf.NavFilter.update_ground_fix`: ``H = [I, 0, ...]``, ``[0, I, 0, ...]``."""
    H = np.zeros((6, N_ERR))
    y = np.empty(6)
    for i in range(6):
        H[i, i] = 1.0
        y[i] = z[i] - x[i]
    return _apply(x, P, H, y, sigma[0:6].copy())


def pack_filter(filt: NavFilter) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, P, qc)`` of ``filt`` for the kernels above: its packed state, covariance and the IMU's
    noise densities squared (the ``qc`` of :meth:`CompiledNavFilter.propagate`)."""
    s = filt.state
    x = np.concatenate((s.r_W, s.v_W, s.q, s.b_g, s.b_a)).astype(float)
    n = filt.noise
    qc = np.repeat([n.gyro_noise_density**2, n.accel_noise_density**2, n.gyro_bias_walk**2, n.accel_bias_walk**2], 3)
    return x, np.array(s.P, float), qc
