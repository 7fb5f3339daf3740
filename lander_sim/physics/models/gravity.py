"""Gravity: inverse-square point mass (eq 7 of the control reference) or uniform field."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import BuildContext, Built, EvalContext, ModelEntry
from lander_sim.yaml_file import Reader


@dataclass
class InverseSquareGravity:
    """``F_W = -GM m r / |r|^3`` on the centre of mass; no torque (uniform over a small body).

    Attributes
    ----------
    gm : float
        Gravitational parameter ``G M`` [m^3/s^2] (Mars: 6.673e-11 * 6.42e23).
    """

    gm: float = c.GM_MARS
    name: str = "gravity"
    calls: int = 0

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        y = ctx.y
        x, yy, z = y[0], y[1], y[2]
        r2 = x * x + yy * yy + z * z
        k = -self.gm * ctx.mass / (r2 * math.sqrt(r2))
        force_W[0] += k * x
        force_W[1] += k * yy
        force_W[2] += k * z

    def potential(self, r_W: np.ndarray, R: np.ndarray, mass: float) -> float:
        """Potential energy ``-GM m / |r|`` [J]."""
        return -self.gm * mass / float(np.linalg.norm(r_W))


@dataclass
class UniformGravity:
    """``F_W = m g_W`` on the centre of mass (small scenes; no planet).

    Attributes
    ----------
    g_W : ndarray (3,)
        Gravitational acceleration, world frame [m/s^2].
    """

    g_W: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -c.SURFACE_GRAVITY]))
    name: str = "gravity"
    calls: int = 0

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        m = ctx.mass
        g = self.g_W
        force_W[0] += m * g[0]
        force_W[1] += m * g[1]
        force_W[2] += m * g[2]

    def potential(self, r_W: np.ndarray, R: np.ndarray, mass: float) -> float:
        """Potential energy ``-m g . r`` [J]."""
        return -mass * float(self.g_W @ r_W)


@dataclass(frozen=True)
class GravityConfig:
    """Scene section ``models.gravity``: ``kind`` ``inverse-square`` (``gm`` [m^3/s^2], planet of
    ``radius`` [m]) or ``uniform`` (``g_W`` [m/s^2], world frame)."""

    kind: str
    gm: float = c.GM_MARS
    radius: float = c.MARS_RADIUS
    g_W: tuple[float, float, float] = (0.0, 0.0, -c.SURFACE_GRAVITY)


def parse(rd: Reader, node: object, path: str) -> GravityConfig:
    g = rd.mapping(node, path, {"kind", "gm", "radius", "g_W"}, ("kind",))
    kind = rd.choice(g["kind"], f"{path}.kind", ("inverse-square", "uniform"))
    cfg = GravityConfig(kind=kind)
    if "gm" in g:
        cfg = replace(cfg, gm=rd.number(g["gm"], f"{path}.gm", 0.0, strict_lo=True))
    if "radius" in g:
        cfg = replace(cfg, radius=rd.number(g["radius"], f"{path}.radius", 0.0, strict_lo=True))
    if "g_W" in g:
        cfg = replace(cfg, g_W=rd.vector3(g["g_W"], f"{path}.g_W"))
    return cfg


def build(cfg: GravityConfig, ctx: BuildContext) -> Built:
    if cfg.kind == "inverse-square":
        return Built(forces=(InverseSquareGravity(gm=cfg.gm),), planet_radius=cfg.radius)
    return Built(forces=(UniformGravity(g_W=np.array(cfg.g_W, dtype=float)),))


ENTRY = ModelEntry("gravity", parse, build)
