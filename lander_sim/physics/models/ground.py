"""Ground contact: touchdown when the altitude falls below L/2, impact instant found inside the step.

As in the original program: after a step that ends below ``R + L/2`` the impact is
placed on the straight segment between the old and new positions where
``|r0 + s (r1 - r0)| = R + L/2`` (a quadratic in ``s``), the state is interpolated
to that fraction of the step, and the touchdown is classified against the scene's
limits (:class:`TouchdownLimits`, scene key ``touchdown``): ``safe`` when the descent
rate, the ground speed and the tilt are all within the safe limits, ``crash`` when any
exceeds its crash limit, ``hard`` in between. The defaults are the original program's
``MAX_IMPACT_DESCENT_RATE`` and ``MAX_IMPACT_GROUND_SPEED`` (1 m/s), no tilt limit, and crash
limits equal to the safe ones (so, as in the original, a touchdown is safe or a crash).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import CRASH, HARD, SAFE, BuildContext, Built, ModelEntry, Touchdown, needs_planet
from lander_sim.yaml_file import Reader


@dataclass(frozen=True)
class TouchdownLimits:
    """Limits a touchdown is classified against (SI: m/s, rad). ``crash_*`` >= ``safe_*``."""

    safe_descent_rate: float = 1.0
    safe_ground_speed: float = 1.0
    safe_tilt: float = math.pi
    crash_descent_rate: float = 1.0
    crash_ground_speed: float = 1.0
    crash_tilt: float = math.pi

    def classify(self, descent_rate: float, ground_speed: float, tilt: float) -> str:
        """:data:`SAFE`, :data:`HARD` or :data:`CRASH`."""
        if descent_rate > self.crash_descent_rate or ground_speed > self.crash_ground_speed or tilt > self.crash_tilt:
            return CRASH
        if descent_rate > self.safe_descent_rate or ground_speed > self.safe_ground_speed or tilt > self.safe_tilt:
            return HARD
        return SAFE


@dataclass
class Ground:
    """Ground of a spherical planet of radius ``planet_radius`` for a lander of size ``size``."""

    planet_radius: float = c.MARS_RADIUS
    size: float = c.LANDER_SIZE
    safe_speed: float = 1.0
    name: str = "ground"
    limits: TouchdownLimits | None = None  # None: safe_speed for both speeds, no tilt limit

    def __post_init__(self) -> None:
        if self.limits is None:
            v = self.safe_speed
            self.limits = TouchdownLimits(v, v, math.pi, v, v, math.pi)

    @property
    def contact_radius(self) -> float:
        """``R + L/2`` [m]: the centre-of-mass distance at which the lander touches."""
        return self.planet_radius + 0.5 * self.size

    def below(self, r_W: np.ndarray) -> bool:
        """True when the altitude is below ``L/2``."""
        return float(r_W @ r_W) < self.contact_radius**2

    def impact_fraction(self, r0_W: np.ndarray, r1_W: np.ndarray) -> float:
        """Smallest ``s`` in [0, 1] with ``|r0 + s (r1 - r0)| = R + L/2`` (0 if already below at r0)."""
        d = r1_W - r0_W
        a = float(d @ d)
        b = 2.0 * float(r0_W @ d)
        cc = float(r0_W @ r0_W) - self.contact_radius**2
        if cc <= 0.0 or a == 0.0:
            return 0.0
        disc = max(b * b - 4.0 * a * cc, 0.0)
        s = (-b - math.sqrt(disc)) / (2.0 * a)
        return min(max(s, 0.0), 1.0)

    def classify(self, fraction: float, r_W: np.ndarray, v_W: np.ndarray, z_B_W: np.ndarray | None = None) -> Touchdown:
        """Touchdown record for the interpolated impact state; ``z_B_W`` is the body z axis in the
        world frame (``None``: upright, tilt 0)."""
        rhat = r_W / float(np.linalg.norm(r_W))
        vr = float(v_W @ rhat)
        ground_speed = float(np.linalg.norm(v_W - vr * rhat))
        tilt = 0.0 if z_B_W is None else math.acos(min(1.0, max(-1.0, float(z_B_W @ rhat) / float(np.linalg.norm(z_B_W)))))
        assert self.limits is not None
        cls = self.limits.classify(-vr, ground_speed, tilt)
        return Touchdown(fraction, -vr, ground_speed, cls == CRASH, tilt, cls)


@dataclass(frozen=True)
class GroundConfig:
    """Scene section ``models.ground``: ``safe_speed`` [m/s]; ``limits``: the scene's ``touchdown``
    section, set by the scene loader (None: ``safe_speed`` for both speeds, no tilt limit)."""

    safe_speed: float = 1.0
    limits: TouchdownLimits | None = None


def parse(rd: Reader, node: object, path: str) -> GroundConfig:
    g = rd.mapping(node, path, {"safe_speed"})
    return GroundConfig(safe_speed=rd.number(g.get("safe_speed", GroundConfig.safe_speed), f"{path}.safe_speed", 0.0,
                                             strict_lo=True))


def build(cfg: GroundConfig, ctx: BuildContext) -> Built:
    return Built(ground=Ground(ctx.planet_radius, ctx.vehicle.size, cfg.safe_speed, limits=cfg.limits))


ENTRY = ModelEntry("ground", parse, build, needs_planet)
