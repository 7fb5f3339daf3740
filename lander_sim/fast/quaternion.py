"""Quaternion kernels on scalars, for compiled loops (the sensors' and the navigation filter's).

The arithmetic of :func:`lander_sim.physics.rotation.quat_mult` (eq 10 of the dynamics reference)
and :func:`~lander_sim.physics.rotation.quat_to_matrix` (eq 13), written element by element so that
numba keeps everything in registers; quaternions are ``(s, x, y, z)``.
"""
from __future__ import annotations

from lander_sim.fast.lander_kernel import njit  # type: ignore[attr-defined]


@njit(cache=True)
def qmul(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    """``a x b`` (eq 10), as :func:`lander_sim.physics.rotation.quat_mult`."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + b0 * a1 + a2 * b3 - a3 * b2,
            a0 * b2 + b0 * a2 + a3 * b1 - a1 * b3,
            a0 * b3 + b0 * a3 + a1 * b2 - a2 * b1)


@njit(cache=True)
def rotation_into(s, a, b, c, R):  # pragma: no cover - compiled
    """World-to-body matrix ``R(q)`` of ``q = (s, a, b, c)`` (eq 13) into ``R`` (3 x 3)."""
    R[0, 0] = s * s + a * a - b * b - c * c
    R[0, 1] = 2.0 * (a * b + s * c)
    R[0, 2] = 2.0 * (a * c - s * b)
    R[1, 0] = 2.0 * (a * b - s * c)
    R[1, 1] = s * s - a * a + b * b - c * c
    R[1, 2] = 2.0 * (s * a + b * c)
    R[2, 0] = 2.0 * (s * b + a * c)
    R[2, 1] = 2.0 * (b * c - s * a)
    R[2, 2] = s * s - a * a - b * b + c * c
