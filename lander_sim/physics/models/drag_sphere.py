"""Cheap drag: a sphere of fixed drag area, force through the centre of mass, no torque."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import EvalContext


@dataclass
class SphereDrag:
    """``F_W = 1/2 rho Cd A |W| W`` with ``W = wind_W - v_W`` the air velocity relative to the body.

    Attributes
    ----------
    cd : float
        Drag coefficient (1.0 in the original program).
    area : float
        Reference area [m^2] (``pi L^2``).
    """

    cd: float = c.SPHERE_DRAG_COEFFICIENT
    area: float = c.SPHERE_DRAG_AREA
    name: str = "drag"
    calls: int = 0

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        rho = ctx.rho
        if rho == 0.0:
            return
        y, wind = ctx.y, ctx.inputs.wind_W
        wx, wy, wz = wind[0] - y[3], wind[1] - y[4], wind[2] - y[5]
        k = 0.5 * rho * self.cd * self.area * math.sqrt(wx * wx + wy * wy + wz * wz)
        force_W[0] += k * wx
        force_W[1] += k * wy
        force_W[2] += k * wz
