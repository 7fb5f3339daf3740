"""Ground contact: touchdown when the altitude falls below L/2, impact instant found inside the step.

As in the original program: after a step that ends below ``R + L/2`` the impact is
placed on the straight segment between the old and new positions where
``|r0 + s (r1 - r0)| = R + L/2`` (a quadratic in ``s``), the state is interpolated
to that fraction of the step, and the touchdown is a crash if the descent rate or
the ground speed exceeds the safe limit (1 m/s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import constants as c


@dataclass(frozen=True)
class Touchdown:
    """Where and how the lander met the ground.

    Attributes
    ----------
    fraction : float
        Fraction ``s`` of the last step at which the impact happened, in [0, 1].
    descent_rate : float
        ``-v . r_hat`` at impact [m/s] (positive downwards).
    ground_speed : float
        Horizontal speed at impact [m/s].
    crashed : bool
        True when either exceeds the safe limit.
    """

    fraction: float
    descent_rate: float
    ground_speed: float
    crashed: bool


@dataclass
class Ground:
    """Ground of a spherical planet of radius ``planet_radius`` for a lander of size ``size``."""

    planet_radius: float = c.MARS_RADIUS
    size: float = c.LANDER_SIZE
    safe_speed: float = 1.0
    name: str = "ground"

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

    def classify(self, fraction: float, r_W: np.ndarray, v_W: np.ndarray) -> Touchdown:
        """Touchdown record for the interpolated impact state."""
        rhat = r_W / float(np.linalg.norm(r_W))
        vr = float(v_W @ rhat)
        ground_speed = float(np.linalg.norm(v_W - vr * rhat))
        crashed = -vr > self.safe_speed or ground_speed > self.safe_speed
        return Touchdown(fraction, -vr, ground_speed, crashed)
