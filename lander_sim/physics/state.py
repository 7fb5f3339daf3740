"""The flat state vector every integrator advances, and a typed view of it.

Layout of ``y`` (float64, length :data:`N_STATE`), all SI units:

========  ==========  ==========================================================
index     name        meaning
========  ==========  ==========================================================
0:3       ``r_W``     position of the centre of mass, planet-centred inertial
                      (world) frame [m]
3:6       ``v_W``     velocity, world frame [m/s]
6:10      ``att``     attitude. Quaternion mode: unit quaternion ``(s, x, y, z)``
                      in the reference's convention, ``R(q)`` maps world to body
                      (eq 12-13), ``x_B = q* x_W q``. Euler mode: ZXZ angles
                      ``(phi, theta, psi)`` in 6:9 (eq 3), slot 9 held at 0.
10:13     ``omega_B`` angular velocity, body frame [rad/s]
13        ``fuel``    fuel mass [kg]
========  ==========  ==========================================================

One layout for both attitude modes keeps every integrator and the snapshot
code mode-agnostic; the attitude *kinematics* (eq 5 or eq 14) live in the
dynamics object, not here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

R_W = slice(0, 3)
V_W = slice(3, 6)
ATT = slice(6, 10)
EULER = slice(6, 9)
OMEGA_B = slice(10, 13)
FUEL = 13
N_STATE = 14

AttitudeMode = Literal["quaternion", "euler"]


@dataclass(frozen=True)
class StateView:
    """A read-only, typed copy of one instant of the flat state.

    Attributes
    ----------
    t : float
        Simulation time [s].
    r_W, v_W : ndarray (3,)
        Position [m] and velocity [m/s] in the planet-centred inertial frame.
    q : ndarray (4,)
        Unit quaternion ``(s, x, y, z)``, world -> body (eq 12-13). In Euler
        mode this is computed from the angles.
    euler : ndarray (3,)
        ZXZ Euler angles ``(phi, theta, psi)`` [rad] (eq 3). In quaternion
        mode this is computed from ``q``.
    omega_B : ndarray (3,)
        Angular velocity in the body frame [rad/s].
    fuel : float
        Fuel mass [kg].
    """

    t: float
    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    omega_B: np.ndarray
    fuel: float


def pack(
    r_W: np.ndarray,
    v_W: np.ndarray,
    attitude: np.ndarray,
    omega_B: np.ndarray,
    fuel: float,
) -> np.ndarray:
    """Build a flat state vector; ``attitude`` is a quaternion (4) or ZXZ angles (3)."""
    y = np.zeros(N_STATE)
    y[R_W] = r_W
    y[V_W] = v_W
    att = np.asarray(attitude, dtype=float)
    if att.shape == (4,):
        y[ATT] = att
    elif att.shape == (3,):
        y[EULER] = att
    else:
        raise ValueError(f"attitude must have 4 (quaternion) or 3 (ZXZ Euler) components, got shape {att.shape}")
    y[OMEGA_B] = omega_B
    y[FUEL] = fuel
    return y
