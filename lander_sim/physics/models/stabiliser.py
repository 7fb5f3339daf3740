"""Attitude stabiliser of the original program: a kinematic aid, not a controller.

After each step it turns the lander so that its body z axis points along the local
vertical ``r_hat`` and sets ``omega_B = 0``. The original rebuilt the whole attitude
from ``up`` and a fixed "left" vector (choosing the yaw arbitrarily); here the
smallest rotation that takes the current body z axis onto ``up`` is applied, so the
yaw is kept (it matters for canted thrusters) and an upright lander is left exactly
as it was.
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.state import ATT, EULER, OMEGA_B, R_W, AttitudeMode


def upright_quaternion(q: np.ndarray, up_W: np.ndarray) -> np.ndarray:
    """Attitude ``p x q`` whose body z axis is ``up_W`` (unit), ``p`` the smallest such world rotation.

    ``q`` read actively rotates body into world (``x_W = q x_B q*``), so a world
    rotation ``p`` applied after it gives ``p x q`` (eq 10, 12).
    """
    z_W = rotation.quat_to_matrix(q)[2]  # third row of world->body = body z in world
    axis = np.cross(z_W, up_W)
    sin_a = float(np.linalg.norm(axis))
    cos_a = float(z_W @ up_W)
    if sin_a < 1e-12:
        if cos_a > 0.0:
            return np.asarray(q, dtype=float).copy()
        # Upside down: any horizontal axis will do; take the body x axis.
        axis = rotation.quat_to_matrix(q)[0]
    p = rotation.axis_angle_to_quat(axis, math.atan2(sin_a, cos_a))
    return rotation.quat_normalise(rotation.quat_mult(p, q))


def stabilise(y: np.ndarray, mode: AttitudeMode) -> None:
    """Apply the stabiliser in place: body z along ``r_hat``, ``omega_B = 0``."""
    r = y[R_W]
    n = float(np.linalg.norm(r))
    if n == 0.0:
        return  # no local vertical at the planet's centre (or in a planet-less scene at the origin)
    up = r / n
    if mode == "quaternion":
        y[ATT] = upright_quaternion(y[ATT], up)
    else:
        q = upright_quaternion(rotation.euler_to_quat(y[EULER]), up)
        y[EULER] = rotation.quat_to_euler(q)
    y[OMEGA_B] = 0.0
