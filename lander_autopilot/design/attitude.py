"""Attitude model of the lander (control reference eq 23, 25, 26, 28).

State ``x = [phi, theta, psi, wx, wy, wz]`` (ZXZ Euler angles [rad], body rates [rad/s]),
input ``u = [t_1 .. t_N]`` (throttles). Linearised about a demand attitude ``E_e`` and body
rate ``omega_e``::

    d/dt [dE]   [A11  A12] [dE]   [ 0 ]
         [dw] = [ 0   A22] [dw] + [B21] du          (eq 28)

``A11``/``A12`` are eq 23's two matrices, ``A22`` eq 25's gyroscopic matrix and
``B21 = -I^-1 S diag(T)`` with ``S = [s_1 .. s_N]``, ``s_i = p_i x d_i`` (eq 26, eq 25).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics.rotation import euler_rates_matrix
from lander_sim.physics.vehicle import Vehicle

from . import DesignError

#: ZXZ Euler angles of an upright lander on the -y axis: keeps eq 5 far from its singularity.
UPRIGHT_EULER = (0.0, math.pi / 2.0, 0.0)


@dataclass(frozen=True)
class AttitudeModel:
    """Linear attitude model (eq 28) about ``E_e``, ``omega_e``.

    Attributes
    ----------
    A : ndarray (6, 6)
    B : ndarray (6, N)
        Column ``i`` is the response of ``[E', w']`` to thruster ``i``'s throttle.
    E_e : ndarray (3,)
        Demand ZXZ Euler angles [rad].
    omega_e : ndarray (3,)
        Demand body rate [rad/s].
    inertia : ndarray (3,)
        Principal moments ``(Ixx, Iyy, Izz)`` [kg m^2] used.
    """

    A: np.ndarray
    B: np.ndarray
    E_e: np.ndarray
    omega_e: np.ndarray
    inertia: np.ndarray


def thrust_torque_matrix(vehicle: Vehicle) -> np.ndarray:
    """``Q = M t``: body torque [N m] per unit throttle, ``M = -S diag(T_i)`` (eq 26), shape (3, N).

    Disabled thrusters get a zero column (they produce nothing whatever the throttle).
    """
    S = vehicle.torque_arms().T  # (3, N): columns s_i = p_i x d_i
    T = np.array([t.max_thrust if t.enabled else 0.0 for t in vehicle.thrusters])
    return -S * T


def euler_kinematics_jacobian(E: np.ndarray, omega_B: np.ndarray) -> np.ndarray:
    """``A11 = d(J(E) omega)/dE`` at ``E``, ``omega`` (eq 23's first matrix)."""
    _, theta, psi = E
    wx, wy, _ = omega_B
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    a = wx * sp + wy * cp
    b = wx * cp - wy * sp
    return np.array(
        [
            [0.0, -a * ct / (st * st), b / st],
            [0.0, 0.0, -a],
            [0.0, a / (st * st), -b * ct / st],
        ]
    )


def gyroscopic_jacobian(inertia: np.ndarray, omega_B: np.ndarray) -> np.ndarray:
    """``A22``: eq 25's matrix, ``d/d omega`` of ``I^-1 (I omega x omega)`` for diagonal ``I``."""
    ixx, iyy, izz = inertia
    wx, wy, wz = omega_B
    al, be, ga = (iyy - izz) / ixx, (izz - ixx) / iyy, (ixx - iyy) / izz
    return np.array([[0.0, al * wz, al * wy], [be * wz, 0.0, be * wx], [ga * wy, ga * wx, 0.0]])


def attitude_model(
    vehicle: Vehicle,
    fuel: float,
    E_e: tuple[float, float, float] | np.ndarray = UPRIGHT_EULER,
    omega_e: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
) -> AttitudeModel:
    """Assemble eq 28 from eq 23 (kinematics), eq 25 (Euler's equations) and eq 26 (thrusters).

    Raises :class:`DesignError` when ``E_e`` is at the Euler singularity (``sin theta = 0``),
    where eq 23 is undefined.
    """
    E = np.asarray(E_e, dtype=float).reshape(-1)
    w = np.asarray(omega_e, dtype=float).reshape(-1)
    if E.shape != (3,) or w.shape != (3,):
        raise DesignError(f"E_e and omega_e need 3 components each, got shapes {E.shape} and {w.shape}")
    if abs(math.sin(E[1])) < 1e-6:
        raise DesignError(f"demand theta = {E[1]!r} rad is at the ZXZ Euler singularity (sin theta = 0)")
    inertia = vehicle.inertia(fuel)
    A = np.zeros((6, 6))
    A[0:3, 0:3] = euler_kinematics_jacobian(E, w)
    A[0:3, 3:6] = euler_rates_matrix(E)
    A[3:6, 3:6] = gyroscopic_jacobian(inertia, w)
    B = np.zeros((6, vehicle.n_thrusters))
    B[3:6, :] = thrust_torque_matrix(vehicle) / inertia[:, None]
    return AttitudeModel(A=A, B=B, E_e=E, omega_e=w, inertia=inertia)


def quaternion_attitude_model(vehicle: Vehicle, fuel: float) -> AttitudeModel:
    """Attitude model at rest in quaternion-vector coordinates ``x = [2 v_err, omega]``.

    With ``q = q_d x dq`` and ``dq ~ (1, dtheta/2)``, eq 14 gives ``dtheta' = omega``
    to first order at rest, so the model is eq 28 with ``J`` replaced by the identity
    and no singularity anywhere: ``A = [[0, I3], [0, 0]]``, same ``B``.
    """
    inertia = vehicle.inertia(fuel)
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    B = np.zeros((6, vehicle.n_thrusters))
    B[3:6, :] = thrust_torque_matrix(vehicle) / inertia[:, None]
    return AttitudeModel(A=A, B=B, E_e=np.full(3, np.nan), omega_e=np.zeros(3), inertia=inertia)
