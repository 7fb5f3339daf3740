"""The compiled thrust-axis attitude (controllers/deorbit/axis_kernel.py) against the numpy formula
it follows, and the helpers the de-orbit laws' periods use instead of numpy's dispatch.

The kernel does numpy's arithmetic in numpy's order, with every dot product as a chain of fused
multiply-adds in index order. Its contract is tested exactly against rational arithmetic; where
numpy's BLAS computes its dot products the same way (OpenBLAS on a CPU with FMA), the attitude is
the numpy formula's to the bit, so the de-orbit flights are unchanged; elsewhere the two differ by
rounding only: a few dozen operations of relative error 2^-53 each on unit vectors, under 1e-14.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from lander_autopilot.controllers.base import value_range
from lander_autopilot.controllers.deorbit import axis_kernel
from lander_autopilot.controllers.deorbit.geometry import (
    mean_of,
    norm3,
    thrust_axis_attitude,
    thrust_axis_attitude_numpy,
)
from lander_sim.physics.rotation import quat_mult, quat_mult_components, quat_normalise, quat_to_matrix

RNG = np.random.default_rng(20261204)
ROUNDING = 1e-14

needs_numba = pytest.mark.skipif(not axis_kernel.HAVE_NUMBA, reason="the kernel needs numba")


def blas_fuses() -> bool:
    """Whether numpy's dot product of doubles is the fused chain: ``(1, a) . (-1, a)`` with
    ``a = 1 + 2^-27`` is ``a^2 - 1`` exactly (``2^-26 + 2^-54``) fused, ``2^-26`` rounded first."""
    a = 1.0 + 2.0**-27
    return float(np.array([1.0, a]).dot(np.array([-1.0, a]))) == 2.0**-26 + 2.0**-54


def exact_chain(x: np.ndarray, y: np.ndarray) -> float:
    """``fma(x2, y2, fma(x1, y1, x0 y0))`` in rational arithmetic, each step rounded once."""
    acc = float(Fraction(x[0]) * Fraction(y[0]))
    for i in (1, 2):
        acc = float(Fraction(x[i]) * Fraction(y[i]) + Fraction(acc))
    return acc


def cases(n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Random attitudes and directions of any length, a tenth of them within 1e-16..1e-8 of body z
    and a tenth of them of minus body z (the kernel's two special branches and their edges)."""
    out = []
    for i in range(n):
        q = quat_normalise(RNG.normal(size=4))
        d = RNG.normal(size=3) * 10.0 ** RNG.uniform(-3, 4)
        if i % 10 in (1, 2):
            sign = 1.0 if i % 10 == 1 else -1.0
            d = sign * 37.0 * quat_to_matrix(q)[2] + RNG.normal(size=3) * 10.0 ** RNG.uniform(-16, -8)
        out.append((q, d))
    return out


@needs_numba
def test_fused_dot3_is_the_exact_fused_chain():
    for _ in range(3000):
        x = RNG.normal(size=3) * 10.0 ** RNG.uniform(-8, 8, size=3)
        y = RNG.normal(size=3) * 10.0 ** RNG.uniform(-8, 8, size=3)
        assert axis_kernel.fused_dot3(*x.tolist(), *y.tolist()) == exact_chain(x, y)


@needs_numba
def test_compiled_attitude_is_the_numpy_formulas():
    exact = blas_fuses()
    for q, d in cases(5000):
        a, b = thrust_axis_attitude(q, d), thrust_axis_attitude_numpy(q, d)
        if exact:
            assert np.array_equal(a, b), (q, d)
        else:
            assert np.max(np.abs(a - b)) < ROUNDING, (q, d)


@needs_numba
def test_compiled_attitude_points_body_z_along_the_direction_and_keeps_the_yaw():
    # the property itself: body +z of the result along d (to rounding), and the rotation from q is
    # about an axis perpendicular to both z's (no turn about the thrust axis)
    for q, d in cases(500):
        z0 = quat_to_matrix(q)[2]
        if z0 @ d < -(1.0 - 1e-6) * np.linalg.norm(d):
            # within 1e-3 rad of a half turn the axis z0 x d / |z0 x d| carries a relative error
            # ~eps / sin(angle) (so does the numpy formula's, bit for bit, test above); exactly
            # opposite, the law's own fallback (next test)
            continue
        q1 = thrust_axis_attitude(q, d)
        assert abs(np.linalg.norm(q1) - 1.0) < ROUNDING
        z1 = quat_to_matrix(q1)[2]
        assert np.max(np.abs(z1 - d / np.linalg.norm(d))) < 1e-12
        if np.linalg.norm(np.cross(z0, d)) > 1e-6 * np.linalg.norm(d):
            # R1 = R0 M^T: body x's turn is the rotation about k = z0 x d, so x1 . k = x0 . k
            k = np.cross(z0, d) / np.linalg.norm(np.cross(z0, d))
            assert abs(quat_to_matrix(q1)[0] @ k - quat_to_matrix(q)[0] @ k) < 1e-12


@needs_numba
def test_parallel_direction_keeps_the_attitude_and_opposite_turns_about_body_x():
    # within PARALLEL_SINE of body z the attitude is kept; of minus body z the fallback turns about
    # body x (the formula's atan2(1, -1): 3/4 of a half turn), the numpy formula's to rounding
    q = quat_normalise(np.array([0.9, 0.1, -0.2, 0.3]))
    R = quat_to_matrix(q)
    assert np.array_equal(thrust_axis_attitude(q, 5.0 * R[2]), q)
    turned = thrust_axis_attitude(q, -R[2])
    assert np.max(np.abs(turned - thrust_axis_attitude_numpy(q, -R[2]))) < ROUNDING
    assert np.max(np.abs(quat_to_matrix(turned)[0] - R[0])) < 1e-12  # body x is the axis: kept
    assert abs(quat_to_matrix(turned)[2] @ R[2] - np.cos(0.75 * np.pi)) < 1e-12


def test_norm3_and_mean_of_are_numpys_to_the_bit():
    # the same BLAS dot product and the same reduction, called without numpy's dispatch
    for _ in range(2000):
        v = RNG.normal(size=3) * 10.0 ** RNG.uniform(-6, 6, size=3)
        u = RNG.uniform(-0.2, 1.2, size=4)
        assert norm3(v) == float(np.linalg.norm(v))
        assert mean_of(u) == float(np.mean(u))


def test_value_range_is_numpys_min_and_max_nan_and_infinities_included():
    # saturate() and the attitude-priority mix read the throttles' range from it
    specials = [math.nan, math.inf, -math.inf, 0.0, -0.0]
    for i in range(2000):
        u = RNG.uniform(-0.5, 1.5, size=4)
        if i % 4 == 0:
            u[RNG.integers(4)] = specials[RNG.integers(len(specials))]
        lo, hi = value_range(u)
        if np.isnan(u).any():
            assert math.isnan(lo) and math.isnan(hi)
        else:
            assert (lo, hi) == (float(u.min()), float(u.max()))


def test_quaternion_product_on_components_is_quat_mult():
    for _ in range(1000):
        a, b = RNG.normal(size=4), RNG.normal(size=4)
        assert np.array_equal(np.array(quat_mult_components(a.tolist(), b.tolist())), quat_mult(a, b))
