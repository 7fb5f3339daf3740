"""Small test problems that satisfy the Dynamics protocol, built on the core's rigid-body equations.

Only the composition is local: Euler's equations come from :mod:`lander_sim.physics.rigid_body`,
and the point-mass gravity is the one-line inverse-square law (eq 7 of the control reference),
so the convergence tests can run on problems with closed-form solutions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lander_sim.physics import rigid_body
from lander_sim.physics.state import OMEGA_B, AttitudeMode, pack

_ZERO3 = np.zeros(3)


@dataclass
class KeplerTop:
    """A torque-free rigid body (principal moments ``inertia``) whose centre of mass orbits a point mass.

    ``gm = 0`` or ``translation=False`` gives a free top; the rotational part is eq 2 with ``Q = 0``.
    """

    inertia: tuple[float, float, float]
    gm: float = 0.0
    attitude: AttitudeMode = "quaternion"
    translation: bool = True
    evaluations: int = 0
    _w: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)

    def accelerations(self, t: float, y: np.ndarray, out: np.ndarray) -> None:
        self.evaluations += 1
        if self.translation and self.gm != 0.0:
            x, yy, z = y[0], y[1], y[2]
            r2 = x * x + yy * yy + z * z
            k = -self.gm / (r2 * math.sqrt(r2))
            out[0], out[1], out[2] = k * x, k * yy, k * z
        else:
            out[0:3] = 0.0
        A, B, C = self.inertia
        rigid_body.omega_dot(A, B, C, y[OMEGA_B], _ZERO3, out[3:6])

    def fuel_rate(self, t: float, y: np.ndarray) -> float:
        return 0.0

    def inertia_B(self, y: np.ndarray) -> np.ndarray:
        return np.asarray(self.inertia, dtype=float)

    def energy(self, y: np.ndarray) -> float:
        """Specific orbital energy plus rotational kinetic energy [J per kg of orbit + J]."""
        A, B, C = self.inertia
        e_rot = rigid_body.kinetic_energy(A, B, C, y[OMEGA_B])
        if not self.translation or self.gm == 0.0:
            return e_rot
        return e_rot + 0.5 * float(y[3:6] @ y[3:6]) - self.gm / float(np.linalg.norm(y[0:3]))


def state(r_W, v_W, attitude, omega_B) -> np.ndarray:
    """Flat state with no fuel."""
    return pack(np.asarray(r_W, float), np.asarray(v_W, float), np.asarray(attitude, float), np.asarray(omega_B, float), 0.0)
