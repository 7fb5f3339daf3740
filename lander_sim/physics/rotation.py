"""Rotation algebra: quaternions and ZXZ Euler angles, in the reference's convention.

Equation numbers refer to "The Extended Mars Lander, Exercise 1: Euler's equations and quaternions"
(the dynamics reference; docs/architecture.md, "References").

Conventions (fixed for the whole project):

* A quaternion is ``(s, x, y, z)`` = ``(s, v)`` (eq 8).
* Rotation matrices map **world to body (local)** coordinates:
  ``x_B = R x_W`` (eq 3, eq 13), and the quaternion form is ``x_B = q* x_W q`` (eq 12).
  Hence ``R(q)`` is the transpose of the usual "active" matrix, and the same
  ``q`` read as an active rotation rotates body into world: that is exactly the
  ROS ``orientation`` of ``base_link`` in the world frame (``(x, y, z, w) = (q1, q2, q3, s)``).
* ZXZ Euler angles ``E = (phi, theta, psi)``, ``R = Rz(psi) Rx(theta) Rz(phi)`` (eq 3).
  The matching quaternion is ``q = q_z(phi) q_x(theta) q_z(psi)`` with ``q_a(angle)`` from eq 9.
* Angular velocity ``omega`` is in the body frame.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def axis_angle_to_quat(axis: np.ndarray, angle: float) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle`` [rad] about unit ``axis`` (eq 9)."""
    a = np.asarray(axis, dtype=float)
    n = np.linalg.norm(a)
    if n == 0.0:
        raise ValueError("axis must be a non-zero vector")
    h = 0.5 * angle
    return np.concatenate(([math.cos(h)], (math.sin(h) / n) * a))


def components(v: np.ndarray | Sequence[float]) -> list[float]:
    """A vector's components as Python numbers: scalar arithmetic on them is the same IEEE
    arithmetic as on numpy's scalars, several times faster."""
    return v.tolist() if isinstance(v, np.ndarray) else list(v)


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of two 3-vectors, ``(a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)``: ``np.cross``'s
    products and differences (so its bits), on scalars, without its axis handling."""
    a0, a1, a2 = components(a)
    b0, b1, b2 = components(b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def quat_mult(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Quaternion product ``q1 x q2`` (eq 10)."""
    return np.array(quat_mult_components(components(q1), components(q2)))


def quat_mult_components(q1: Sequence[float], q2: Sequence[float]) -> tuple[float, float, float, float]:
    """:func:`quat_mult` on the components (Python numbers in, out): for a caller that reads them."""
    s1, x1, y1, z1 = q1
    s2, x2, y2, z2 = q2
    return (
        s1 * s2 - x1 * x2 - y1 * y2 - z1 * z2,
        s1 * x2 + s2 * x1 + y1 * z2 - z1 * y2,
        s1 * y2 + s2 * y1 + z1 * x2 - x1 * z2,
        s1 * z2 + s2 * z1 + x1 * y2 - y1 * x2,
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate ``q* = (s, -v)`` (eq 11)."""
    s, x, y, z = components(q)
    return np.array([s, -x, -y, -z])


def quat_normalise(q: np.ndarray) -> np.ndarray:
    """``q / |q|``; raises on a zero quaternion, which has no rotation."""
    n = math.sqrt(float(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]))
    if n == 0.0:
        raise ValueError("cannot normalise a zero quaternion")
    return np.asarray(q, dtype=float) / n


def world_to_body(q: np.ndarray, x_W: np.ndarray) -> np.ndarray:
    """Transform a world-frame vector into the body frame: ``(0, x_B) = q* (0, x_W) q`` (eq 12)."""
    return quat_to_matrix(q) @ x_W


def body_to_world(q: np.ndarray, x_B: np.ndarray) -> np.ndarray:
    """Inverse of :func:`world_to_body`: ``x_W = R(q)^T x_B``."""
    return quat_to_matrix(q).T @ x_B


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """World-to-body rotation matrix of a unit quaternion (eq 13)."""
    s, a, b, c = components(q)
    return np.array(
        [
            [s * s + a * a - b * b - c * c, 2.0 * (a * b + s * c), 2.0 * (a * c - s * b)],
            [2.0 * (a * b - s * c), s * s - a * a + b * b - c * c, 2.0 * (s * a + b * c)],
            [2.0 * (s * b + a * c), 2.0 * (b * c - s * a), s * s - a * a - b * b + c * c],
        ]
    )


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (with ``s >= 0``) of a world-to-body rotation matrix; inverse of eq 13.

    Shepperd's method: pick the largest of the four squared components so the
    division is always well conditioned.
    """
    R = np.asarray(R, dtype=float)
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    # Eq 13 is the transpose of the active matrix, so off-diagonal signs flip.
    cand = np.array([tr, R[0, 0], R[1, 1], R[2, 2]])
    k = int(np.argmax(cand))
    if k == 0:
        s = 0.5 * math.sqrt(max(1.0 + tr, 0.0))
        f = 0.25 / s
        q = np.array([s, (R[1, 2] - R[2, 1]) * f, (R[2, 0] - R[0, 2]) * f, (R[0, 1] - R[1, 0]) * f])
    elif k == 1:
        a = 0.5 * math.sqrt(max(1.0 + 2.0 * R[0, 0] - tr, 0.0))
        f = 0.25 / a
        q = np.array([(R[1, 2] - R[2, 1]) * f, a, (R[0, 1] + R[1, 0]) * f, (R[0, 2] + R[2, 0]) * f])
    elif k == 2:
        b = 0.5 * math.sqrt(max(1.0 + 2.0 * R[1, 1] - tr, 0.0))
        f = 0.25 / b
        q = np.array([(R[2, 0] - R[0, 2]) * f, (R[0, 1] + R[1, 0]) * f, b, (R[1, 2] + R[2, 1]) * f])
    else:
        c = 0.5 * math.sqrt(max(1.0 + 2.0 * R[2, 2] - tr, 0.0))
        f = 0.25 / c
        q = np.array([(R[0, 1] - R[1, 0]) * f, (R[0, 2] + R[2, 0]) * f, (R[1, 2] + R[2, 1]) * f, c])
    if q[0] < 0.0:
        q = -q
    return q / np.linalg.norm(q)


def quat_dot(q: np.ndarray, omega_B: np.ndarray) -> np.ndarray:
    """Rate of change of the attitude quaternion, ``q' = 1/2 q x (0, omega)`` (eq 14)."""
    s, a, b, c = q
    wx, wy, wz = omega_B
    return 0.5 * np.array(
        [
            -a * wx - b * wy - c * wz,
            s * wx + b * wz - c * wy,
            s * wy + c * wx - a * wz,
            s * wz + a * wy - b * wx,
        ]
    )


def quat_ddot(q: np.ndarray, omega_B: np.ndarray, omega_dot_B: np.ndarray) -> np.ndarray:
    """Second derivative of the quaternion, ``q'' = 1/2 q x (0, omega') - 1/4 |omega|^2 q`` (eq 15)."""
    w2 = float(omega_B[0] ** 2 + omega_B[1] ** 2 + omega_B[2] ** 2)
    return quat_dot(q, omega_dot_B) - 0.25 * w2 * np.asarray(q, dtype=float)


def quat_exp_step(q: np.ndarray, omega_B: np.ndarray, dt: float) -> np.ndarray:
    """Advance ``q`` by a constant body rate over ``dt``: ``q x exp((0, omega dt / 2))``.

    This is the exact flow of eq 14 for constant ``omega``; it maps unit
    quaternions to unit quaternions, so ``|q| = 1`` holds by construction.
    """
    wx, wy, wz = omega_B
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    h = 0.5 * wn * dt
    if wn * dt < 1e-8:
        # Taylor series of sin(h)/|w|: avoids 0/0 and keeps full precision.
        k = 0.5 * dt * (1.0 - h * h / 6.0)
    else:
        k = math.sin(h) / wn
    dq = np.array([math.cos(h), k * wx, k * wy, k * wz])
    return quat_mult(q, dq)


# --- ZXZ Euler angles -------------------------------------------------------

#: Smallest |sin theta| used as a divisor in eq 5 and eq 7. Exactly at gimbal lock
#: J is infinite; flooring the divisor keeps the numbers finite (and wildly
#: wrong, which is the behaviour a student should see) instead of raising
#: ZeroDivisionError and killing the process. Callers warn via near_gimbal_lock.
SIN_THETA_FLOOR = 1e-12


def _guarded_sin(theta: float) -> float:
    """``sin(theta)`` with its magnitude floored at :data:`SIN_THETA_FLOOR`, sign kept."""
    st = math.sin(theta)
    if abs(st) < SIN_THETA_FLOOR:
        return SIN_THETA_FLOOR if st >= 0.0 else -SIN_THETA_FLOOR
    return st



def euler_to_matrix(E: np.ndarray) -> np.ndarray:
    """World-to-body matrix ``R = Rz(psi) Rx(theta) Rz(phi)`` of ZXZ angles (eq 3)."""
    phi, theta, psi = E
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return np.array(
        [
            [cp * cf - sp * ct * sf, cp * sf + sp * ct * cf, sp * st],
            [-sp * cf - cp * ct * sf, -sp * sf + cp * ct * cf, cp * st],
            [st * sf, -st * cf, ct],
        ]
    )


def matrix_to_euler(R: np.ndarray) -> np.ndarray:
    """ZXZ angles of a world-to-body matrix, inverse of eq 3.

    Returns ``theta`` in ``[0, pi]`` and ``phi, psi`` in ``(-pi, pi]``. At the
    singularity (``sin theta = 0``) only ``phi +- psi`` is defined; ``psi = 0``
    is chosen there.
    """
    R = np.asarray(R, dtype=float)
    st = math.hypot(R[2, 0], R[2, 1])
    theta = math.atan2(st, R[2, 2])
    if st > 1e-12:
        phi = math.atan2(R[2, 0], -R[2, 1])
        psi = math.atan2(R[0, 2], R[1, 2])
    else:
        phi = math.atan2(R[0, 1], R[0, 0])
        psi = 0.0
    return np.array([phi, theta, psi])


def euler_to_quat(E: np.ndarray) -> np.ndarray:
    """Quaternion of ZXZ angles: ``q = q_z(phi) x q_x(theta) x q_z(psi)`` (eq 3, 9, 10, 12)."""
    phi, theta, psi = E
    qf = np.array([math.cos(0.5 * phi), 0.0, 0.0, math.sin(0.5 * phi)])
    qt = np.array([math.cos(0.5 * theta), math.sin(0.5 * theta), 0.0, 0.0])
    qp = np.array([math.cos(0.5 * psi), 0.0, 0.0, math.sin(0.5 * psi)])
    return quat_mult(quat_mult(qf, qt), qp)


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """ZXZ angles of a unit quaternion (via eq 13 and the inverse of eq 3): :func:`matrix_to_euler`
    on the entries of :func:`quat_to_matrix` it reads, computed alone (the same arithmetic)."""
    s, a, b, c = components(q)
    r20, r21, r22 = 2.0 * (s * b + a * c), 2.0 * (b * c - s * a), s * s - a * a - b * b + c * c
    st = math.hypot(r20, r21)
    theta = math.atan2(st, r22)
    if st > 1e-12:
        phi = math.atan2(r20, -r21)
        psi = math.atan2(2.0 * (a * c - s * b), 2.0 * (s * a + b * c))
    else:
        phi = math.atan2(2.0 * (a * b + s * c), s * s + a * a - b * b - c * c)
        psi = 0.0
    return np.array([phi, theta, psi])


def euler_rates_matrix(E: np.ndarray) -> np.ndarray:
    """``J`` of eq 5, ``E' = J omega``. Singular where ``sin theta = 0`` (gimbal lock).

    At the singularity the divisor is floored (:data:`SIN_THETA_FLOOR`): the
    result is finite but meaningless, as in the seed program's Euler variant.
    """
    _, theta, psi = E
    st, ct = _guarded_sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    return np.array(
        [
            [sp / st, cp / st, 0.0],
            [cp, -sp, 0.0],
            [-ct * sp / st, -ct * cp / st, 1.0],
        ]
    )


def euler_rates_matrix_inv(E: np.ndarray) -> np.ndarray:
    """``J^-1`` of eq 4, ``omega = J^-1 E'``; defined everywhere, rank-deficient at gimbal lock."""
    _, theta, psi = E
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    return np.array(
        [
            [sp * st, cp, 0.0],
            [cp * st, -sp, 0.0],
            [ct, 0.0, 1.0],
        ]
    )


def euler_rates_matrix_dot(E: np.ndarray, E_dot: np.ndarray) -> np.ndarray:
    """Time derivative ``J'`` of eq 5's ``J`` (eq 7), given ``E`` and ``E'``."""
    _, theta, psi = E
    _, th_d, ps_d = E_dot
    st, ct = _guarded_sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    tt = st / ct if ct != 0.0 else math.inf
    return np.array(
        [
            [-sp / (st * tt) * th_d + cp / st * ps_d, -cp / (st * tt) * th_d - sp / st * ps_d, 0.0],
            [-ps_d * sp, -ps_d * cp, 0.0],
            [sp / (st * st) * th_d - ct * cp / st * ps_d, cp / (st * st) * th_d + ct * sp / st * ps_d, 0.0],
        ]
    )


def euler_ddot(E: np.ndarray, omega_B: np.ndarray, omega_dot_B: np.ndarray) -> np.ndarray:
    """Second derivative of the Euler angles, ``E'' = J' omega + J omega'`` (eq 6)."""
    J = euler_rates_matrix(E)
    E_dot = J @ omega_B
    return euler_rates_matrix_dot(E, E_dot) @ omega_B + J @ omega_dot_B


def near_gimbal_lock(E: np.ndarray, threshold: float) -> bool:
    """True when ``|sin theta|`` is below ``threshold`` (section 3.2's 'close encounter')."""
    return abs(math.sin(E[1])) < threshold
