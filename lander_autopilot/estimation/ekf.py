"""Error-state extended Kalman filter of the lander's navigation: IMU propagation, aiding updates.

**State.** Nominal ``x = (r_W, v_W, q, b_g, b_a)``: position [m] and velocity [m/s] in the
planet-centred world frame, the attitude quaternion (world -> body, :mod:`lander_sim.physics.rotation`),
gyro bias [rad/s] and accelerometer bias [m/s^2]. Error state (15)::

    dx = [dr (3), dv (3), dth (3), db_g (3), db_a (3)],   q_true = q x dq(dth)

``dth`` is a small rotation about body axes (the *local* or *multiplicative* attitude error:
Sola, "Quaternion kinematics for the error-state Kalman filter", arXiv:1711.02508, 2017, section 7;
Markley and Crassidis, *Fundamentals of Spacecraft Attitude Determination and Control*, 2014,
section 6.2), so the covariance ``P`` (15 x 15) never meets the quaternion's unit-norm constraint.

**Propagation** over ``dt`` with the IMU's ``omega_m``, ``f_m`` (:mod:`lander_sim.sensors.imu`) as
the input, ``omega = omega_m - b_g``, ``f = f_m - b_a``, ``C = R(q)^T`` (body -> world)::

    r += v dt + a dt^2 / 2,   v += a dt,   a = C f + g(r),   q = q x exp(omega dt / 2)

and the error dynamics (Sola 2017, eq 237, with the gravity gradient
``G = GM (3 r_hat r_hat^T - I) / |r|^3``)::

    dr' = dv
    dv' = G dr - C [f x] dth - C db_a - C n_a
    dth' = -[omega x] dth - db_g - n_g
    db_g' = n_bg,   db_a' = n_ba

discretised as ``Phi = I + F dt + (F dt)^2 / 2`` and ``Q_d = G_n Q_c G_n^T dt`` with
``Q_c = diag(N_g^2, N_a^2, K_g^2, K_a^2)`` per axis: the IMU's white-noise densities and bias walks.

**Updates** ``z = h(x) + v``, ``v ~ N(0, R)``: the innovation ``y = z - h(x)`` (for the star
tracker ``y = 2 vec(q^* x q_m)``, the multiplicative update), its covariance
``S = H P H^T + R``, the gain ``K = P H^T S^-1``, the error estimate ``dx = K y`` injected into the
nominal state (``q <- q x dq(dth)``) and ``P <- (I - K H) P (I - K H)^T + K R K^T`` (Joseph form,
symmetric and positive by construction). ``R`` is diagonal for every sensor, so a vector
measurement is applied as scalar updates one component after the other (Bierman, *Factorization
Methods for Discrete Sequential Estimation*, 1977): no matrix inverse; the normalised innovation
squared ``NIS = y^T S^-1 y`` is computed for the whole vector first. Jacobians ``H``:

* star tracker: ``[0, 0, I, 0, 0]``;
* radar altimeter, slant range ``s`` along the body beam ``d_B`` to the sphere ``|p| = R_p``,
  ``p = r + s d``, ``d = C d_B``: ``H_r = -p^T / (p . d)``, ``H_th = s p^T C [d_B x] / (p . d)``
  (implicit differentiation of ``|r + s d|^2 = R_p^2``, with ``dd = -C [d_B x] dth``);
* Doppler velocimeter, ``z = R v``: ``H_v = R``, ``H_th = [(R v) x]``;
* ground fix: ``[I, 0, ...]`` and ``[0, I, 0, ...]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np

from lander_sim.physics.constants import GM_MARS
from lander_sim.physics.rotation import quat_conj, quat_exp_step, quat_mult, quat_normalise, quat_to_matrix

N_ERR = 15
DR, DV, DTH, DBG, DBA = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)


class EstimationError(ValueError):
    """A filter input that cannot be used (wrong shape, not finite); the message says which."""


def skew(a: np.ndarray) -> np.ndarray:
    """``[a x]``: ``skew(a) @ b = a x b``."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def small_rotation(th: np.ndarray) -> np.ndarray:
    """``dq(th)``: unit quaternion of the rotation vector ``th`` [rad]."""
    a = math.sqrt(float(th @ th))
    if a < 1e-12:
        return quat_normalise(np.array([1.0, 0.5 * th[0], 0.5 * th[1], 0.5 * th[2]]))
    k = math.sin(0.5 * a) / a
    return np.array([math.cos(0.5 * a), k * th[0], k * th[1], k * th[2]])


def attitude_error(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``th`` with ``q = q_ref x dq(th)`` (body axes of ``q_ref``), the shorter way round."""
    d = quat_mult(quat_conj(q_ref), q)
    if d[0] < 0.0:
        d = -d
    v = d[1:]
    n = math.sqrt(float(v @ v))
    if n < 1e-15:
        return 2.0 * v
    return (2.0 * math.atan2(n, float(d[0])) / n) * v


@dataclass(frozen=True)
class NoiseModel:
    """The IMU's noise as the filter models it (SI): white-noise densities ``gyro_noise_density``
    [rad/s/sqrt(Hz)], ``accel_noise_density`` [m/s^2/sqrt(Hz)] and bias random-walk densities
    ``gyro_bias_walk`` [rad/s/sqrt(s)], ``accel_bias_walk`` [m/s^2/sqrt(s)]: the same names and
    units as the IMU's parameter table (:mod:`lander_sim.sensors.imu`)."""

    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_walk: float
    accel_bias_walk: float


@dataclass
class NavState:
    """Nominal state and error covariance (module docstring)."""

    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    P: np.ndarray
    t: float = 0.0


@dataclass(frozen=True)
class Update:
    """What one aiding update did: sensor ``key``, innovation ``y``, its covariance ``S`` and
    ``nis = y^T S^-1 y`` (chi-square of ``len(y)`` degrees of freedom for a consistent filter)."""

    key: str
    y: np.ndarray
    S: np.ndarray
    nis: float


@dataclass
class NavFilter:
    """The error-state EKF (module docstring). Bad input raises :class:`EstimationError` and leaves
    the state as it was; ``rejected`` counts such inputs by sensor key."""

    state: NavState
    noise: NoiseModel
    gm: float = GM_MARS
    planet_radius: float = 0.0
    rejected: dict[str, int] = field(default_factory=dict)

    # --- propagation -------------------------------------------------------------------------

    def propagate(self, omega_m: np.ndarray, f_m: np.ndarray, dt: float) -> None:
        """Advance the state and covariance over ``dt`` [s] with the IMU sample ``omega_m``, ``f_m``."""
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
        F = np.zeros((N_ERR, N_ERR))
        F[DR, DV] = np.eye(3)
        rhat = s.r_W / math.sqrt(r2)
        F[DV, DR] = self.gm * (3.0 * np.outer(rhat, rhat) - np.eye(3)) / (r2 * math.sqrt(r2))
        F[DV, DTH] = -C @ skew(f)
        F[DV, DBA] = -C
        F[DTH, DTH] = -skew(w)
        F[DTH, DBG] = -np.eye(3)
        Fd = F * dt
        Phi = np.eye(N_ERR) + Fd + 0.5 * Fd @ Fd
        Gn = np.zeros((N_ERR, 12))
        Gn[DV, 3:6] = -C
        Gn[DTH, 0:3] = -np.eye(3)
        Gn[DBG, 6:9] = np.eye(3)
        Gn[DBA, 9:12] = np.eye(3)
        n = self.noise
        qc = np.repeat([n.gyro_noise_density**2, n.accel_noise_density**2, n.gyro_bias_walk**2, n.accel_bias_walk**2], 3)
        Qd = (Gn * qc) @ Gn.T * dt
        s.r_W = s.r_W + s.v_W * dt + 0.5 * a * dt * dt
        s.v_W = s.v_W + a * dt
        s.q = quat_normalise(quat_exp_step(s.q, w, dt))
        P = Phi @ s.P @ Phi.T + Qd
        s.P = 0.5 * (P + P.T)
        s.t += dt

    # --- updates -----------------------------------------------------------------------------

    def update_star_tracker(self, q_m: np.ndarray, sigma: np.ndarray) -> Update:
        """Multiplicative attitude update from a measured quaternion ``q_m`` with per-axis noise ``sigma`` [rad]."""
        q_m = self._vec("star_tracker", q_m, 4)
        if abs(math.sqrt(float(q_m @ q_m)) - 1.0) > 1e-6:
            self._reject("star_tracker", f"expected a unit quaternion, got norm {math.sqrt(float(q_m @ q_m))!r}")
        H = np.zeros((3, N_ERR))
        H[:, DTH] = np.eye(3)
        return self._update("star_tracker", attitude_error(self.state.q, q_m), H, self._sigma("star_tracker", sigma, 3))

    def predict_slant_range(self, beam_B: np.ndarray) -> tuple[float, np.ndarray] | None:
        """``(s, H)``: predicted slant range [m] along body ``beam_B`` and its Jacobian (1 x 15), or
        None when the predicted beam misses the planet."""
        s_ = self.state
        C = quat_to_matrix(s_.q).T
        d_B = np.asarray(beam_B, float) / math.sqrt(float(np.dot(beam_B, beam_B)))
        d = C @ d_B
        rd = float(s_.r_W @ d)
        disc = rd * rd - (float(s_.r_W @ s_.r_W) - self.planet_radius**2)
        if disc < 0.0:
            return None
        s = -rd - math.sqrt(disc)
        if s < 0.0:
            return None
        p = s_.r_W + s * d
        pd = float(p @ d)
        H = np.zeros((1, N_ERR))
        H[0, DR] = -p / pd
        H[0, DTH] = s * (p @ C @ skew(d_B)) / pd
        return s, H

    def update_altimeter(self, rho_m: float, sigma: float, beam_B: np.ndarray) -> Update | None:
        """Scalar slant-range update (``beam_B``: the altimeter's beam, body frame); None when the
        predicted beam misses the planet (the measurement is then not used)."""
        z = self._vec("altimeter", np.atleast_1d(rho_m), 1)
        sig = self._sigma("altimeter", np.atleast_1d(sigma), 1)
        pred = self.predict_slant_range(beam_B)
        if pred is None:
            self.rejected["altimeter"] = self.rejected.get("altimeter", 0) + 1
            return None
        s, H = pred
        return self._update("altimeter", z - s, H, sig)

    def update_doppler(self, v_m: np.ndarray, sigma: np.ndarray) -> Update:
        """Body-frame velocity update, three scalar updates."""
        z = self._vec("doppler", v_m, 3)
        sig = self._sigma("doppler", sigma, 3)
        R = quat_to_matrix(self.state.q)
        vb = R @ self.state.v_W
        H = np.zeros((3, N_ERR))
        H[:, DV] = R
        H[:, DTH] = skew(vb)
        return self._update("doppler", z - vb, H, sig)

    def update_ground_fix(self, z: np.ndarray, sigma: np.ndarray) -> Update:
        """World-frame position and velocity update, six scalar updates."""
        z = self._vec("ground_fix", z, 6)
        sig = self._sigma("ground_fix", sigma, 6)
        H = np.zeros((6, N_ERR))
        H[0:3, DR] = np.eye(3)
        H[3:6, DV] = np.eye(3)
        return self._update("ground_fix", z - np.concatenate((self.state.r_W, self.state.v_W)), H, sig)

    def _update(self, key: str, y: np.ndarray, H: np.ndarray, sigma: np.ndarray) -> Update:
        s = self.state
        Rm = np.diag(sigma**2)
        S = H @ s.P @ H.T + Rm
        nis = float(y @ np.linalg.solve(S, y))
        P = s.P
        dx = np.zeros(N_ERR)
        for i in range(len(y)):
            h = H[i]
            # the innovation of component i after the components before it have been applied
            yi = float(y[i] - h @ dx)
            Ph = P @ h
            si = float(h @ Ph) + sigma[i] ** 2
            k = Ph / si
            dx = dx + k * yi
            IKH = np.eye(N_ERR) - np.outer(k, h)
            P = IKH @ P @ IKH.T + sigma[i] ** 2 * np.outer(k, k)
        s.r_W = s.r_W + dx[DR]
        s.v_W = s.v_W + dx[DV]
        s.q = quat_normalise(quat_mult(s.q, small_rotation(dx[DTH])))
        s.b_g = s.b_g + dx[DBG]
        s.b_a = s.b_a + dx[DBA]
        s.P = 0.5 * (P + P.T)
        return Update(key, y, S, nis)

    # --- input checks ------------------------------------------------------------------------

    def _reject(self, key: str, why: str) -> NoReturn:
        self.rejected[key] = self.rejected.get(key, 0) + 1
        raise EstimationError(f"{key}: {why}")

    def _vec(self, key: str, v: object, n: int) -> np.ndarray:
        try:
            a = np.asarray(v, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            self._reject(key, f"expected {n} numbers, got {v!r}")
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            self._reject(key, f"expected {n} finite numbers, got {v!r}")
        return a

    def _sigma(self, key: str, sigma: object, n: int) -> np.ndarray:
        s = self._vec(key, sigma, n)
        if np.any(s <= 0.0):
            self._reject(key, f"noise standard deviations must be > 0, got {s.tolist()}")
        return s
