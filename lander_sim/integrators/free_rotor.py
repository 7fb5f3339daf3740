"""The torque-free rigid rotor's Dullweber-Leimkuhler-McLachlan step on plain floats.

A leaf module (``math`` only): the geometric integrator (:mod:`lander_sim.integrators.geometric`,
whose docstring derives the splitting) calls it, and its compiled form
(:mod:`lander_sim.fast.rk_kernels`) compiles this very function with numba.
"""
from __future__ import annotations

import math

import numpy as np


def free_rotor_step(
    s: float, x: float, y: float, z: float,
    L1: float, L2: float, L3: float,
    A: float, B: float, C: float,
    dt: float,
) -> tuple[float, float, float, float, float, float, float]:
    """One DLM step of the torque-free rotor on plain floats: ``(q, L_B) -> (q, L_B)`` after ``dt``.

    ``q = (s, x, y, z)`` is the world-to-body quaternion, ``L_B`` the body angular momentum
    [kg m^2/s], ``(A, B, C)`` the principal moments [kg m^2]. Each quaternion update is eq 10
    written out for the right factor ``(c, sn e_i)`` (a principal-axis exponential map, the
    special case of :func:`lander_sim.physics.rotation.quat_exp_step` that the tests check it
    against); plain floats rather than tiny numpy arrays because this is the inner loop of
    1e5-1e6-step runs, and numba compiles this very function for the fast path.
    """
    h = 0.5 * dt
    # R1(h): L turns by -w1 h about e1; q <- q x exp(w1 h e1 / 2).
    a = L1 / A * h
    c, sn = math.cos(a), math.sin(a)
    L2, L3 = c * L2 + sn * L3, c * L3 - sn * L2
    c, sn = math.cos(0.5 * a), math.sin(0.5 * a)
    s, x, y, z = c * s - sn * x, c * x + sn * s, c * y + sn * z, c * z - sn * y
    # R2(h)
    a = L2 / B * h
    c, sn = math.cos(a), math.sin(a)
    L3, L1 = c * L3 + sn * L1, c * L1 - sn * L3
    c, sn = math.cos(0.5 * a), math.sin(0.5 * a)
    s, x, y, z = c * s - sn * y, c * x - sn * z, c * y + sn * s, c * z + sn * x
    # R3(dt)
    a = L3 / C * dt
    c, sn = math.cos(a), math.sin(a)
    L1, L2 = c * L1 + sn * L2, c * L2 - sn * L1
    c, sn = math.cos(0.5 * a), math.sin(0.5 * a)
    s, x, y, z = c * s - sn * z, c * x + sn * y, c * y - sn * x, c * z + sn * s
    # R2(h)
    a = L2 / B * h
    c, sn = math.cos(a), math.sin(a)
    L3, L1 = c * L3 + sn * L1, c * L1 - sn * L3
    c, sn = math.cos(0.5 * a), math.sin(0.5 * a)
    s, x, y, z = c * s - sn * y, c * x - sn * z, c * y + sn * s, c * z + sn * x
    # R1(h)
    a = L1 / A * h
    c, sn = math.cos(a), math.sin(a)
    L2, L3 = c * L2 + sn * L3, c * L3 - sn * L2
    c, sn = math.cos(0.5 * a), math.sin(0.5 * a)
    s, x, y, z = c * s - sn * x, c * x + sn * s, c * y + sn * z, c * z - sn * y
    return s, x, y, z, L1, L2, L3


def free_rotor_run(q: np.ndarray, L_B: np.ndarray, inertia_B: np.ndarray, dt: float, n: int) -> None:
    """Advance ``q`` (4,) and ``L_B`` (3,) in place by ``n`` torque-free DLM steps of ``dt``."""
    s, x, y, z = (float(v) for v in q)
    L1, L2, L3 = (float(v) for v in L_B)
    A, B, C = (float(v) for v in inertia_B)
    for _ in range(n):
        s, x, y, z, L1, L2, L3 = free_rotor_step(s, x, y, z, L1, L2, L3, A, B, C, dt)
    q[:] = (s, x, y, z)
    L_B[:] = (L1, L2, L3)
