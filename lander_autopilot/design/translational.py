"""Translational + attitude model of the lander about a hover (seed 2's section 6 question: "Can you
control the ground speed of the lander as well as the orientation and altitude?").

**Local horizontal frame** (ROS REP 103, ENU: x east, y north, z up; name ``local_enu``). At a point
``r_W`` of the planet-centred world frame ``mars``: ``up = r_W / |r_W|``,
``east = normalise(z_W x up)`` (``x_W`` where ``up`` is parallel to ``z_W``, the poles),
``north = up x east``. For the linear model the origin is the point on the surface below the
hover, so ``p_U`` is the altitude; the flight laws evaluate the frame at the lander's current
position each step (only velocities and directions matter to them). On the world ``-y`` axis, where
every scene starts, ``(east, north, up) = (x_W, z_W, -y_W)`` and an upright lander (ZXZ Euler
``(0, pi/2, 0)``) has its body axes along east, north and up.

**Full linear model** (12 states, ``N`` throttles)::

    x = [p_E p_N p_U  v_E v_N v_U  phi theta psi  wx wy wz],  u = [t_1 .. t_N]
    p' = v
    v' = (T_v t_e / m) C dE + F u / m          (thrust vector; gravity balanced at t_e, eq 14)
    [E' w'] = eq 28 (A11 A12 A22 B21)          (control reference eq 23, 25, 26, 28)

``C`` maps a small Euler-angle change to the horizontal tilt of the thrust: the body rotation is
``delta_B = J(E)^-1 dE`` (dynamics reference eq 5), and rotating ``up`` by ``delta`` moves it by
``delta x up = (delta_N, -delta_E, 0)`` (ENU), so ``a_E = g delta_N``, ``a_N = -g delta_E``.
``F = R_BL diag(...)``: column ``i`` is thruster ``i``'s force ``-d_i T_i`` at full throttle,
turned from the body into the local frame (the canted layout has a body-x component). Gravity is
taken constant over the manoeuvre (flat ground: the reference's eq 16 choice); the dropped terms
are the gradients ``2GM/z^3`` (vertical) and ``-GM/z^3`` (horizontal), about 1e-6 s^-2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics.rotation import (
    euler_rates_matrix_inv,
    euler_to_quat,
    quat_to_matrix,
)
from lander_sim.physics.vehicle import Vehicle

from . import DesignError
from .altitude import altitude_model
from .attitude import UPRIGHT_EULER, attitude_model

#: ROS frame id of the local horizontal frame (``header.frame_id`` of ``/lander/demand_velocity``).
LOCAL_FRAME = "local_enu"

FULL_STATES = ("p_E", "p_N", "p_U", "v_E", "v_N", "v_U", "phi", "theta", "psi", "wx", "wy", "wz")


def local_frame(r_W: np.ndarray) -> np.ndarray:
    """Rows ``(east, north, up)`` of the local ENU frame at ``r_W`` (world frame), shape (3, 3).

    ``M @ x_W`` gives a world vector's ENU components. Plain floats: this runs every control step.
    """
    x, y, z = (float(c) for c in r_W)
    r = math.sqrt(x * x + y * y + z * z)
    if r == 0.0:
        raise DesignError("local frame undefined at the planet's centre (r_W = 0)")
    ux, uy, uz = x / r, y / r, z / r
    ex, ey = -uy, ux  # z_W x up = (-u_y, u_x, 0)
    n = math.hypot(ex, ey)
    if n < 1e-12:  # over a pole: east is x_W by convention
        ex, ey, n = 1.0, 0.0, 1.0
    ex, ey = ex / n, ey / n
    # north = up x east, with east_z = 0
    nx, ny, nz = -uz * ey, uz * ex, ux * ey - uy * ex
    return np.array([[ex, ey, 0.0], [nx, ny, nz], [ux, uy, uz]])


@dataclass(frozen=True)
class FullModel:
    """Linear translational + attitude model about a hover (module docstring), local ENU frame.

    Attributes
    ----------
    A : ndarray (12, 12)
    B : ndarray (12, N)
    states : tuple of str
        :data:`FULL_STATES`.
    g : float
        ``T_v t_e / m`` [m/s^2]: the hover thrust acceleration, equal to local gravity.
    t_e : float
        Hover throttle (eq 14).
    mass : float
        [kg].
    E_e : ndarray (3,)
        Euler angles linearised about [rad].
    """

    A: np.ndarray
    B: np.ndarray
    states: tuple[str, ...]
    g: float
    t_e: float
    mass: float
    E_e: np.ndarray


def tilt_matrix(E_e: np.ndarray) -> np.ndarray:
    """``C`` (3 x 3): ENU horizontal acceleration per unit ``g`` per radian of Euler-angle change.

    ``delta_B = J^-1 dE`` (eq 5), ``delta_L = R_BL delta_B``, ``d(up) = delta_L x up``.
    """
    R_LB = body_to_local(E_e)
    d_up = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # delta -> delta x e_U
    return d_up @ R_LB @ euler_rates_matrix_inv(np.asarray(E_e, dtype=float))


def body_to_local(E_e: np.ndarray) -> np.ndarray:
    """Rotation body -> local ENU for a lander at ZXZ Euler angles ``E_e`` on the world ``-y`` axis."""
    R_WB = quat_to_matrix(euler_to_quat(np.asarray(E_e, dtype=float))).T  # body -> world
    return local_frame(np.array([0.0, -1.0, 0.0])) @ R_WB


def full_model(
    vehicle: Vehicle, fuel: float, altitude: float = 500.0, E_e: tuple[float, float, float] = UPRIGHT_EULER
) -> FullModel:
    """Assemble the 12-state model (module docstring) at a hover ``altitude`` [m] with ``fuel`` [kg]."""
    alt = altitude_model(vehicle, fuel, altitude)
    att = attitude_model(vehicle, fuel, E_e)
    m = alt.mass
    g = alt.T_v * alt.t_e / m
    n = vehicle.n_thrusters
    A = np.zeros((12, 12))
    A[0:3, 3:6] = np.eye(3)
    A[3:6, 6:9] = g * tilt_matrix(att.E_e)
    A[6:12, 6:12] = att.A
    F_B = np.array([-t.direction_B * (t.max_thrust if t.enabled else 0.0) for t in vehicle.thrusters]).T  # (3, N)
    B = np.zeros((12, n))
    B[3:6, :] = body_to_local(att.E_e) @ F_B / m
    B[6:12, :] = att.B
    # The frame rotations leave ~1e-16 where the exact entries are 0: clean them so the report shows zeros.
    A[np.abs(A) < 1e-12 * np.abs(A).max()] = 0.0
    B[np.abs(B) < 1e-12 * np.abs(B).max()] = 0.0
    return FullModel(A=A, B=B, states=FULL_STATES, g=g, t_e=alt.t_e, mass=m, E_e=att.E_e)


def horizontal_velocity_model() -> tuple[np.ndarray, np.ndarray]:
    """Outer loop of the ground-speed law, per horizontal axis: ``x = [int e dt, e]``, ``e = v - v_d``.

    The input is the horizontal acceleration the tilted thrust gives (``a = g tan(tilt)``, realised
    exactly by the law, rows 4-5 of :func:`full_model` to first order): ``A = [[0, 1], [0, 0]]``,
    ``B = [0, 1]``. Placing poles ``p1, p2`` gives ``k_i = p1 p2``, ``k_p = -(p1 + p2)``.
    """
    return np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]])
