"""The truth a sensor samples, read from a :class:`~lander_sim.simulation.Simulation`.

The specific force is what the dynamics' accelerations leave once gravity is taken out::

    f_W = a_W - g_W(r_W),      f_B = R_BW f_W

(``g_W = -GM r / |r|^3`` for the inverse-square field, the constant ``g_W`` for the uniform one,
zero without gravity): the thrust, drag and parachute per unit mass.
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


def truth_of(sim: Simulation, planet_radius: float | None = None) -> Truth:
    """The simulation's truth now (its inputs as set for the coming step give the specific force).

    ``planet_radius`` defaults to the scene's gravity radius (0 without inverse-square gravity).
    """
    y = sim.y
    q = y[6:10].copy() if sim.scene.attitude == "quaternion" else rotation.euler_to_quat(y[6:9])
    if planet_radius is None:
        g = sim.scene.models.get("gravity")
        planet_radius = float(g.radius) if g is not None and g.kind == "inverse-square" else 0.0
    return Truth(t=sim.t, r_W=y[0:3].copy(), v_W=y[3:6].copy(), q=q, omega_B=y[10:13].copy(),
                 f_B=specific_force_B(sim.dynamics, sim.t, y), planet_radius=planet_radius)
