"""What every sensor sees (the truth at a sample time) and gives (a measurement), and the noise processes.

**Noise** (IEEE Std 952-1997, the Allan-variance model of inertial sensors; Groves, *Principles
of GNSS, Inertial, and Multisensor Integrated Navigation Systems*, 2nd ed., 2013, section 4.4):

* white noise of density ``N`` [unit/sqrt(Hz)], seen through an output averaged over ``dt`` [s],
  has the per-sample standard deviation ``sigma = N / sqrt(dt)``;
* a bias ``b`` drawn once at switch-on, ``b(0) ~ N(0, b0^2)`` per axis, which then walks:
  ``b(t + dt) = b(t) + K sqrt(dt) n``, ``n ~ N(0, 1)``, so ``Var b(t) = b0^2 + K^2 t`` (the
  bias instability as a random walk of density ``K`` [unit/sqrt(s)]).

Every draw comes from the sensor's own ``numpy.random.Generator`` (PCG64), seeded from the suite's
seed and the sensor's key (:mod:`.suite`), in a fixed order per sample: the same seed and the same
truth give byte-identical measurements.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Truth:
    """The true state a sensor samples, all SI.

    ``r_W``, ``v_W``: position and velocity, planet-centred world frame (the planet does not turn,
    so ``v_W`` is also the velocity over the ground); ``q``: attitude quaternion (world -> body,
    :mod:`lander_sim.physics.rotation`); ``omega_B``: body rate [rad/s]; ``f_B``: specific force
    (non-gravitational force per unit mass) in the body frame [m/s^2]; ``planet_radius`` [m]
    (0: no planet, no ground to range to).
    """

    t: float
    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    omega_B: np.ndarray
    f_B: np.ndarray
    planet_radius: float = 0.0


@dataclass(frozen=True)
class Measurement:
    """One sample: sensor ``key``, time ``t`` [s], the value ``z`` and the standard deviation
    ``sigma`` of its white noise per component (what a filter takes as ``R = diag(sigma^2)``)."""

    key: str
    t: float
    z: np.ndarray
    sigma: np.ndarray


class RandomWalkBias:
    """A bias of ``n`` axes: ``b(0) ~ N(0, b0^2)``, then ``b += K sqrt(dt) N(0, 1)`` (module docstring)."""

    def __init__(self, n: int, b0: float, walk: float, rng: np.random.Generator) -> None:
        self.walk = walk
        self.rng = rng
        self.value = b0 * rng.standard_normal(n)

    def advance(self, dt: float) -> np.ndarray:
        """Walk over ``dt`` [s] (>= 0) and return the bias."""
        if dt > 0.0 and self.walk > 0.0:
            self.value = self.value + self.walk * math.sqrt(dt) * self.rng.standard_normal(self.value.size)
        return self.value


def white_sigma(density: float, dt: float) -> float:
    """``N / sqrt(dt)``: standard deviation of white noise of density ``N`` averaged over ``dt``."""
    return density / math.sqrt(dt)
