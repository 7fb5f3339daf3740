"""Exponential Martian atmosphere: ``rho = rho0 exp(-h / H)`` below the exosphere, zero above."""
from __future__ import annotations

import math
from dataclasses import dataclass

from lander_sim.physics import constants as c


@dataclass(frozen=True)
class Atmosphere:
    """Density model of the original program.

    Attributes
    ----------
    surface_density : float
        ``rho0`` [kg/m^3] (0.017).
    scale_height : float
        ``H`` [m] (11 km).
    exosphere : float
        Altitude above which the density is zero [m] (200 km).
    """

    surface_density: float = c.ATMOSPHERE_SURFACE_DENSITY
    scale_height: float = c.ATMOSPHERE_SCALE_HEIGHT
    exosphere: float = c.EXOSPHERE_ALTITUDE

    def density(self, altitude: float) -> float:
        """Air density [kg/m^3] at ``altitude`` [m] above the surface."""
        if altitude > self.exosphere:
            return 0.0
        return self.surface_density * math.exp(-altitude / self.scale_height)
