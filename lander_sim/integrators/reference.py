"""Closed-form reference solutions for checking integrators: Kepler orbits, the torque-free symmetric top.

Used by the convergence tests and the work-precision benchmarks (``bench/integrators.py``).
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.physics import rotation


def kepler_state(t: float, gm: float, a: float, e: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity [m, m/s] at time ``t`` on an ellipse in the x-y plane, periapsis on +x at t=0.

    Mean anomaly ``M = n t``, Kepler's equation ``M = E - e sin E`` solved by Newton to round-off.
    """
    n = math.sqrt(gm / a**3)
    M = n * t
    E = M if e < 0.8 else math.pi
    for _ in range(50):
        dE = (E - e * math.sin(E) - M) / (1.0 - e * math.cos(E))
        E -= dE
        if abs(dE) < 1e-16:
            break
    cE, sE = math.cos(E), math.sin(E)
    b = a * math.sqrt(1.0 - e * e)
    r = np.array([a * (cE - e), b * sE, 0.0])
    Edot = n / (1.0 - e * cE)
    v = np.array([-a * sE * Edot, b * cE * Edot, 0.0])
    return r, v


def kepler_initial(gm: float, a: float, e: float) -> tuple[np.ndarray, np.ndarray]:
    """State at periapsis (t = 0) of :func:`kepler_state`."""
    return kepler_state(0.0, gm, a, e)


def symmetric_top(t: float, A: float, C: float, q0: np.ndarray, omega0_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Torque-free symmetric top (``A = B``): attitude and body rate at ``t``.

    ``L_W`` is fixed; in the body ``omega_B = L_B / A + lam e3`` with ``lam = (1/C - 1/A) L3``
    constant, so the motion is a world rotation about ``L_W`` at ``|L| / A`` composed with a
    body rotation about ``e3`` at ``lam``: ``q(t) = exp_W(L_W |L| t / (2A|L|)) x q0 x exp_B(lam t e3 / 2)``.
    In the body, ``(w1, w2)`` turns at ``(C - A) w3 / A`` and ``w3`` is constant.
    """
    I = np.array([A, A, C])
    L_B0 = I * omega0_B
    L_W = rotation.body_to_world(q0, L_B0)
    Ln = float(np.linalg.norm(L_W))
    lam = (1.0 / C - 1.0 / A) * L_B0[2]
    half = 0.5 * Ln / A * t
    q_world = np.concatenate(([math.cos(half)], math.sin(half) * L_W / Ln))
    q_body = rotation.axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), lam * t)
    q = rotation.quat_mult(rotation.quat_mult(q_world, q0), q_body)
    Omega = (C - A) * omega0_B[2] / A
    c, s = math.cos(Omega * t), math.sin(Omega * t)
    w1, w2, w3 = omega0_B
    # w1' = -Omega w2, w2' = Omega w1 from eq 1 with A = B.
    omega = np.array([c * w1 - s * w2, s * w1 + c * w2, w3])
    return q, omega


def quat_distance(q1: np.ndarray, q2: np.ndarray) -> float:
    """``min(|q1 - q2|, |q1 + q2|)``: q and -q are the same rotation."""
    return float(min(np.linalg.norm(q1 - q2), np.linalg.norm(q1 + q2)))


def kepler_propagate(r0: np.ndarray, v0: np.ndarray, gm: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact two-body flow over ``h`` from any bound state, by Lagrange's f and g in the eccentric anomaly.

    With ``sigma0 = r0.v0 / sqrt(gm)`` the change ``dE`` solves
    ``sqrt(gm/a^3) h = dE - (1 - r0/a) sin dE + sigma0/sqrt(a) (1 - cos dE)`` (Newton to round-off).
    """
    r0 = np.asarray(r0, float)
    v0 = np.asarray(v0, float)
    rn = float(np.linalg.norm(r0))
    a = 1.0 / (2.0 / rn - float(v0 @ v0) / gm)
    sig = float(r0 @ v0) / math.sqrt(gm)
    sa = math.sqrt(a)
    M = math.sqrt(gm / a**3) * h
    dE = M
    for _ in range(60):
        F = dE - (1.0 - rn / a) * math.sin(dE) + sig / sa * (1.0 - math.cos(dE)) - M
        dF = 1.0 - (1.0 - rn / a) * math.cos(dE) + sig / sa * math.sin(dE)
        step = F / dF
        dE -= step
        if abs(step) < 1e-16:
            break
    f = 1.0 - a / rn * (1.0 - math.cos(dE))
    g = h - math.sqrt(a**3 / gm) * (dE - math.sin(dE))
    r1 = f * r0 + g * v0
    r1n = float(np.linalg.norm(r1))
    fd = -math.sqrt(gm * a) / (r1n * rn) * math.sin(dE)
    gd = 1.0 - a / r1n * (1.0 - math.cos(dE))
    return r1, fd * r0 + gd * v0
