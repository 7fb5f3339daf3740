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
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.fast.lander_kernel import HAVE_NUMBA, njit  # type: ignore[attr-defined]
from lander_sim.physics.rotation import quat_exp_step, quat_mult, quat_normalise, quat_to_matrix

from .ekf import DBA, DBG, DR, DTH, DV, N_ERR, NavFilter, NavState, Update, small_rotation

__all__ = ["HAVE_NUMBA", "CompiledNavFilter", "compiled_copy", "covariance_propagate", "sequential_update"]


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
