"""Euler's equations for a rigid body with diagonal inertia (eq 2 of the dynamics reference).

``omega' = I^-1 ((I omega) x omega + Q)`` with ``I = diag(A, B, C)``, all in the body frame.
For the lander ``I = m diag(k^2)`` at the current mass; as in the original program the
``I' omega`` term of a body losing mass is neglected (fuel burns slowly: at most 2 kg/s
against 100-200 kg).
"""
from __future__ import annotations

import numpy as np


def omega_dot(A: float, B: float, C: float, omega_B: np.ndarray, Q_B: np.ndarray, out: np.ndarray) -> None:
    """Write the body angular acceleration [rad/s^2] of eq 2 (eq 1 componentwise) into ``out[0:3]``.

    Plain float arithmetic: this sits in the hot loop, where building small
    arrays for ``I @ omega`` and ``np.cross`` would dominate the cost.
    """
    w1, w2, w3 = float(omega_B[0]), float(omega_B[1]), float(omega_B[2])
    # (I w) x w, expanded: the eq 1 terms (B - C) w2 w3 etc.
    out[0] = ((B - C) * w2 * w3 + Q_B[0]) / A
    out[1] = ((C - A) * w3 * w1 + Q_B[1]) / B
    out[2] = ((A - B) * w1 * w2 + Q_B[2]) / C


def kinetic_energy(A: float, B: float, C: float, omega_B: np.ndarray) -> float:
    """Rotational kinetic energy ``1/2 omega . I omega`` [J]."""
    w1, w2, w3 = omega_B
    return 0.5 * (A * w1 * w1 + B * w2 * w2 + C * w3 * w3)
