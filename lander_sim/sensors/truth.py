"""The truth a sensor samples, read from a :class:`~lander_sim.simulation.Simulation`.

The specific force is what the dynamics' accelerations leave once gravity is taken out::

    f_W = a_W - g_W(r_W),      f_B = R_BW f_W

(``g_W = -GM r / |r|^3`` for the inverse-square field, the constant ``g_W`` for the uniform one,
zero without gravity): the thrust, drag and parachute per unit mass. :func:`truth_of` gives it at an
instant. An IMU integrates over its interval (it outputs angle and velocity increments), and
:func:`truth_after_step` gives what it sees over a simulation step from ``t - dt`` to ``t``:

    omega_B = log(q(t - dt)^* x q(t)) / dt
    f_B = R_BW(t - dt) [(v(t) - v(t - dt)) / dt - (g_W(r(t - dt)) + g_W(r(t))) / 2]

the constant body rate that turns the attitude exactly as the step did, and the velocity increment
less gravity (trapezoidal, error O(dt^2) of the gradient) resolved in the body axes at the start of
the interval, as a strapdown algorithm's sculling correction resolves it (Savage, "Strapdown
Inertial Navigation Integration Algorithm Design Part 2: Velocity and Position Algorithms", J.
Guidance, Control, and Dynamics 21(2), 1998).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.models.gravity import InverseSquareGravity, UniformGravity

from .base import Truth

if TYPE_CHECKING:
    from lander_sim.physics.dynamics import LanderDynamics
    from lander_sim.simulation import Simulation


def gravity_W(dyn: LanderDynamics, r_W: np.ndarray) -> np.ndarray:
    """Gravitational acceleration [m/s^2] of the dynamics' gravity model at ``r_W``."""
    g = dyn.model("gravity")
    if isinstance(g, InverseSquareGravity):
        r2 = float(r_W @ r_W)
        return -g.gm * r_W / (r2 * math.sqrt(r2))
    if isinstance(g, UniformGravity):
        return np.array(g.g_W, dtype=float)
    return np.zeros(3)


def specific_force_B(dyn: LanderDynamics, t: float, y: np.ndarray) -> np.ndarray:
    """``f_B`` [m/s^2] at state ``y`` under the dynamics' current inputs (module docstring)."""
    acc = np.zeros(6)
    yy = np.array(y, dtype=float)
    dyn.accelerations(t, yy, acc)
    f_W = acc[0:3] - gravity_W(dyn, yy[0:3])
    return dyn.rotation_matrix(yy) @ f_W


def _quat(sim: Simulation, y: np.ndarray) -> np.ndarray:
    return y[6:10].copy() if sim.scene.attitude == "quaternion" else rotation.euler_to_quat(y[6:9])


def _radius(sim: Simulation) -> float:
    g = sim.scene.models.get("gravity")
    return float(g.radius) if g is not None and g.kind == "inverse-square" else 0.0


def rotation_vector(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """``th`` [rad] with ``q1 = q0 x dq(th)``: the rotation from ``q0`` to ``q1`` about ``q0``'s body axes."""
    d = rotation.quat_mult(rotation.quat_conj(q0), q1)
    if d[0] < 0.0:
        d = -d
    v = d[1:]
    n = math.sqrt(float(v @ v))
    return 2.0 * v if n < 1e-15 else (2.0 * math.atan2(n, float(d[0])) / n) * v


def truth_after_step(sim: Simulation, y_before: np.ndarray, dt: float) -> Truth:
    """The truth at ``sim.t`` with the body rate and specific force averaged over the step of ``dt`` [s]
    that started from ``y_before`` (module docstring)."""
    y = sim.y
    q0, q1 = _quat(sim, y_before), _quat(sim, y)
    g = 0.5 * (gravity_W(sim.dynamics, y_before[0:3]) + gravity_W(sim.dynamics, y[0:3]))
    f_W = (y[3:6] - y_before[3:6]) / dt - g
    return Truth(t=sim.t, r_W=y[0:3].copy(), v_W=y[3:6].copy(), q=q1, omega_B=rotation_vector(q0, q1) / dt,
                 f_B=rotation.quat_to_matrix(q0) @ f_W, planet_radius=_radius(sim))


def truth_of(sim: Simulation, planet_radius: float | None = None) -> Truth:
    """The simulation's truth now (its inputs as set for the coming step give the specific force).

    ``planet_radius`` defaults to the scene's gravity radius (0 without inverse-square gravity).
    """
    y = sim.y
    if planet_radius is None:
        planet_radius = _radius(sim)
    return Truth(t=sim.t, r_W=y[0:3].copy(), v_W=y[3:6].copy(), q=_quat(sim, y), omega_B=y[10:13].copy(),
                 f_B=specific_force_B(sim.dynamics, sim.t, y), planet_radius=planet_radius)
