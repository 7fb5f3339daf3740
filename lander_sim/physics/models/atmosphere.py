"""Exponential Martian atmosphere: ``rho = rho0 exp(-h / H)`` below the exosphere, zero above."""
from __future__ import annotations

import math
from dataclasses import dataclass

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import BuildContext, Built, ModelEntry, needs_planet
from lander_sim.yaml_file import Reader


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


#: The original program's atmosphere (every shipped scene's default): what the controllers model.
MARS_ATMOSPHERE = Atmosphere()


def parse(rd: Reader, node: object, path: str) -> Atmosphere:
    """Scene section ``models.atmosphere`` (the fields of :class:`Atmosphere`, each > 0)."""
    a = rd.mapping(node, path, {"surface_density", "scale_height", "exosphere"})
    return Atmosphere(**{k: rd.number(v, f"{path}.{k}", 0.0, strict_lo=True) for k, v in a.items()})


def build(cfg: Atmosphere, ctx: BuildContext) -> Built:
    return Built(atmosphere=cfg)  # immutable: the scene's config is the model


ENTRY = ModelEntry("atmosphere", parse, build, needs_planet)
