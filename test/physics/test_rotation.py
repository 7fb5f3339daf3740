"""Every identity of eq 3-15 of the dynamics reference (rotation algebra).

Tolerances: exact identities hold to rounding, so 1e-12 on O(1) quantities
(a few dozen flops of ~1e-16 each). Finite-difference checks use central
differences with step h, whose truncation error is O(h^2 * third derivative):
with h = 1e-5 and O(1) derivatives that is ~1e-10, plus rounding ~eps/h ~ 1e-11;
we allow 1e-7 (margin for derivatives up to ~1e3 near |sin theta| = 0.1).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from lander_sim.physics import rotation as rot

RNG = np.random.default_rng(20130918)
EXACT = 1e-12
FD = 1e-7
H = 1e-5


def random_quats(n: int = 50) -> list[np.ndarray]:
    return [rot.quat_normalise(RNG.normal(size=4)) for _ in range(n)]


def random_euler(n: int = 50, margin: float = 0.1) -> list[np.ndarray]:
    """ZXZ angles away from the singularity: theta in [margin, pi - margin]."""
    return [np.array([RNG.uniform(-math.pi, math.pi), RNG.uniform(margin, math.pi - margin), RNG.uniform(-math.pi, math.pi)]) for _ in range(n)]


def Rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])


def Rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, s], [0, -s, c]])


def skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0.0]])


# --- quaternions (eq 9-15) ----------------------------------------------------


def test_eq9_axis_angle_is_unit_and_fixes_its_axis():
    for _ in range(50):
        axis = RNG.normal(size=3)
        angle = RNG.uniform(-2 * math.pi, 2 * math.pi)
        q = rot.axis_angle_to_quat(axis, angle)
        assert abs(np.linalg.norm(q) - 1.0) < EXACT
        # The rotation axis is invariant under the rotation (eq 12).
        assert np.allclose(rot.world_to_body(q, axis), axis, atol=EXACT * np.linalg.norm(axis) * 10)


def test_eq9_about_z_matches_eq3_single_rotation():
    for a in np.linspace(-3, 3, 13):
        q = rot.axis_angle_to_quat(np.array([0, 0, 1.0]), a)
        assert np.allclose(rot.quat_to_matrix(q), Rz(a), atol=EXACT)


def test_eq10_product_composes_rotations_and_is_associative():
    qs = random_quats(60)
    for q1, q2, q3 in zip(qs[0::3], qs[1::3], qs[2::3]):
        # x_B = (q1 q2)* x (q1 q2) = q2* (q1* x q1) q2, so R(q1 q2) = R(q2) R(q1).
        assert np.allclose(rot.quat_to_matrix(rot.quat_mult(q1, q2)), rot.quat_to_matrix(q2) @ rot.quat_to_matrix(q1), atol=EXACT)
        assert np.allclose(rot.quat_mult(rot.quat_mult(q1, q2), q3), rot.quat_mult(q1, rot.quat_mult(q2, q3)), atol=EXACT)
        assert abs(np.linalg.norm(rot.quat_mult(q1, q2)) - 1.0) < EXACT


def test_eq10_scalar_vector_form():
    for q1, q2 in zip(random_quats(20), random_quats(20)):
        s1, v1, s2, v2 = q1[0], q1[1:], q2[0], q2[1:]
        expect = np.concatenate(([s1 * s2 - v1 @ v2], s1 * v2 + s2 * v1 + np.cross(v1, v2)))
        assert np.allclose(rot.quat_mult(q1, q2), expect, atol=EXACT)


def test_eq11_conjugate_inverts_a_unit_quaternion():
    for q in random_quats():
        assert np.allclose(rot.quat_mult(q, rot.quat_conj(q)), [1, 0, 0, 0], atol=EXACT)
        assert np.allclose(rot.quat_mult(rot.quat_conj(q), q), [1, 0, 0, 0], atol=EXACT)


def test_eq12_eq13_conjugation_equals_matrix_and_matrix_is_a_rotation():
    for q in random_quats():
        x = RNG.normal(size=3)
        p = rot.quat_mult(rot.quat_mult(rot.quat_conj(q), np.concatenate(([0.0], x))), q)
        assert abs(p[0]) < EXACT
        R = rot.quat_to_matrix(q)
        assert np.allclose(p[1:], R @ x, atol=EXACT * 10)
        assert np.allclose(rot.world_to_body(q, x), p[1:], atol=EXACT * 10)
        assert np.allclose(rot.body_to_world(q, rot.world_to_body(q, x)), x, atol=EXACT * 10)
        assert np.allclose(R @ R.T, np.eye(3), atol=EXACT)
        assert abs(np.linalg.det(R) - 1.0) < EXACT


def test_matrix_to_quat_inverts_eq13_up_to_sign():
    for q in random_quats(200):
        q2 = rot.matrix_to_quat(rot.quat_to_matrix(q))
        assert min(np.linalg.norm(q2 - q), np.linalg.norm(q2 + q)) < 1e-10


def test_eq14_quat_dot_matches_finite_difference_of_exact_flow():
    # quat_exp_step is the exact flow for constant omega: a central difference of it
    # has truncation error O(H^2 |omega|^3) ~ 1e-9 for |omega| ~ 1.
    for q in random_quats(20):
        w = RNG.normal(size=3)
        fd = (rot.quat_exp_step(q, w, H) - rot.quat_exp_step(q, w, -H)) / (2 * H)
        assert np.allclose(rot.quat_dot(q, w), fd, atol=FD)
        # and eq 14's scalar-vector form
        s, v = q[0], q[1:]
        assert np.allclose(rot.quat_dot(q, w), 0.5 * np.concatenate(([-v @ w], s * w + np.cross(v, w))), atol=EXACT)


def test_eq15_quat_ddot_matches_derivative_of_eq14_along_a_trajectory():
    # omega(t) = w0 + a t; q(t) from a tight ODE solve of eq 14 (rtol 1e-12), then
    # d/dt [quat_dot(q(t), omega(t))] by central difference (error O(h^2) ~ 1e-8 at h = 1e-4).
    w0, a = np.array([0.3, -0.8, 1.1]), np.array([0.5, 0.2, -0.4])
    sol = solve_ivp(lambda t, q: rot.quat_dot(q, w0 + a * t), (0, 1.0), rot.quat_normalise(np.array([0.9, 0.1, -0.3, 0.2])),
                    rtol=1e-12, atol=1e-14, dense_output=True, method="DOP853")
    h = 1e-4
    for t in (0.2, 0.5, 0.8):
        fd = (rot.quat_dot(sol.sol(t + h), w0 + a * (t + h)) - rot.quat_dot(sol.sol(t - h), w0 + a * (t - h))) / (2 * h)
        assert np.allclose(rot.quat_ddot(sol.sol(t), w0 + a * t, a), fd, atol=1e-7)


# --- ZXZ Euler angles (eq 3-7) -------------------------------------------------


def test_eq3_matrix_is_the_product_of_three_rotations():
    for E in random_euler(30, margin=0.0):
        assert np.allclose(rot.euler_to_matrix(E), Rz(E[2]) @ Rx(E[1]) @ Rz(E[0]), atol=EXACT)


def test_euler_quaternion_matrix_round_trips_away_from_singularity():
    for E in random_euler():
        q = rot.euler_to_quat(E)
        assert np.allclose(rot.quat_to_matrix(q), rot.euler_to_matrix(E), atol=EXACT)
        assert np.allclose(rot.matrix_to_euler(rot.euler_to_matrix(E)), E, atol=1e-10)
        assert np.allclose(rot.quat_to_euler(q), E, atol=1e-10)
        q2 = rot.euler_to_quat(rot.quat_to_euler(q))
        assert min(np.linalg.norm(q2 - q), np.linalg.norm(q2 + q)) < 1e-10
        assert np.allclose(rot.euler_to_matrix(rot.matrix_to_euler(rot.quat_to_matrix(q))), rot.quat_to_matrix(q), atol=1e-10)


def test_matrix_to_euler_at_the_singularity_still_reproduces_the_matrix():
    for E in ([0.3, 0.0, -0.5], [1.0, math.pi, 0.2]):
        R = rot.euler_to_matrix(np.array(E))
        assert np.allclose(rot.euler_to_matrix(rot.matrix_to_euler(R)), R, atol=1e-10)


def test_eq4_eq5_J_inverse_times_J_is_identity():
    for E in random_euler():
        assert np.allclose(rot.euler_rates_matrix_inv(E) @ rot.euler_rates_matrix(E), np.eye(3), atol=1e-10)
        assert np.allclose(rot.euler_rates_matrix(E) @ rot.euler_rates_matrix_inv(E), np.eye(3), atol=1e-10)


def test_eq4_maps_euler_rates_to_body_angular_velocity():
    # World-to-body R with body rates omega: R' = -[omega]x R, so [omega]x = -R' R^T.
    for E in random_euler(20):
        Ed = RNG.normal(size=3)
        Rd = (rot.euler_to_matrix(E + H * Ed) - rot.euler_to_matrix(E - H * Ed)) / (2 * H)
        W = -Rd @ rot.euler_to_matrix(E).T
        w_fd = np.array([W[2, 1], W[0, 2], W[1, 0]])
        assert np.allclose(rot.euler_rates_matrix_inv(E) @ Ed, w_fd, atol=FD)


def test_eq7_J_dot_matches_finite_difference():
    for E in random_euler(30):
        Ed = RNG.normal(size=3)
        fd = (rot.euler_rates_matrix(E + H * Ed) - rot.euler_rates_matrix(E - H * Ed)) / (2 * H)
        assert np.allclose(rot.euler_rates_matrix_dot(E, Ed), fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_eq6_euler_ddot_is_the_second_derivative_of_the_angles():
    # E(t) = E0 + b t + c t^2 has E'' = 2c exactly; omega(t) = J^-1(E) E' (eq 4), omega' by central difference.
    for E0 in random_euler(20, margin=0.3):
        b, c = RNG.normal(size=3), RNG.normal(size=3)

        def omega(t: float) -> np.ndarray:
            return rot.euler_rates_matrix_inv(E0 + b * t + c * t * t) @ (b + 2 * c * t)

        wd = (omega(H) - omega(-H)) / (2 * H)
        assert np.allclose(rot.euler_ddot(E0, omega(0.0), wd), 2 * c, atol=1e-6)


def test_gimbal_lock_is_reported_and_J_stays_finite_at_the_singularity():
    assert rot.near_gimbal_lock(np.array([0.0, 0.0, 0.0]), 1e-3)
    assert rot.near_gimbal_lock(np.array([0.0, math.pi - 1e-4, 0.0]), 1e-3)
    assert not rot.near_gimbal_lock(np.array([0.0, 0.1, 0.0]), 1e-3)
    # Exactly at sin(theta) = 0 eq 5 divides by zero; the guard keeps the process alive
    # with finite (meaningless) numbers, and J^-1 (eq 4) is rank deficient there.
    E = np.zeros(3)
    assert np.all(np.isfinite(rot.euler_rates_matrix(E)))
    assert np.all(np.isfinite(rot.euler_rates_matrix_dot(E, np.array([0.0, 1.0, 0.0]))))
    assert np.linalg.matrix_rank(rot.euler_rates_matrix_inv(E)) == 2


def test_cross3_is_np_cross_to_the_bit():
    # the same three products and differences as np.cross, so equal bits (not a tolerance)
    for _ in range(2000):
        a = RNG.normal(size=3) * 10.0 ** RNG.uniform(-6, 6, size=3)
        b = RNG.normal(size=3) * 10.0 ** RNG.uniform(-6, 6, size=3)
        assert np.array_equal(rot.cross3(a, b), np.cross(a, b))
    assert np.array_equal(rot.cross3([1, 2, 3], [4, 5, 6]), np.cross([1, 2, 3], [4, 5, 6]))


def test_quat_to_euler_is_matrix_to_euler_of_eq13_to_the_bit():
    # the entries of eq 13 it reads, computed alone by the same arithmetic: equal bits, at the
    # singularity too (sin theta under 1e-12 takes the other branch)
    qs = random_quats(2000) + [rot.quat_normalise(np.array([1.0, 0.0, 0.0, z])) for z in RNG.normal(size=50)]
    qs += [rot.quat_normalise(np.array([1.0, x, 0.0, 0.3])) for x in 1e-14 * RNG.normal(size=50)]
    for q in qs:
        assert np.array_equal(rot.quat_to_euler(q), rot.matrix_to_euler(rot.quat_to_matrix(q)))
