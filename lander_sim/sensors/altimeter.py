"""Radar altimeter: slant range along a body-fixed beam to the ground (a sphere of the planet's radius).

Measurement model: the beam leaves the centre of mass along ``d_W = R_BW^T d_B``; the range is the
nearest root ``s > 0`` of ``|r_W + s d_W|^2 = R^2``::

    s = -(r . d) - sqrt((r . d)^2 - (|r|^2 - R^2))

and the output is ``rho_m = s + b + n``, ``n ~ N(0, sigma^2)``, ``sigma^2 = sigma_0^2 + (k s)^2``
(a floor and a fraction of the range), ``b`` a switch-on bias. No output when the beam misses the
planet (tilted past the horizon), or the range exceeds ``max_range``. Upright over flat ground the
range is the altitude; tilted by ``theta`` it is ``h / cos(theta)`` to first order in ``h / R``.

Defaults: after the Mars Science Laboratory's Terminal Descent Sensor, a Ka-band pulse-Doppler
radar of six beams that gave range and velocity at 20 Hz from about 4 km above the ground down to
touchdown with errors of the order of 1-2 % (Pollard and Sadowy, "Mars Science Laboratory
Terminal Descent Sensor", IEEE Aerospace Conference, 2005). One beam along body ``-z`` here.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_sim.physics.rotation import body_to_world

from .base import Measurement, Truth
from .params import Param

TDS = "MSL Terminal Descent Sensor (Pollard and Sadowy 2005)"

PARAMS = (
    Param("rate", 20.0, "Hz", "output rate", TDS, 0.0, None, True),
    Param("noise_floor", 0.5, "m", "range noise floor, 1 sigma", TDS),
    Param("noise_fraction", 0.01, "-", "range noise as a fraction of the range, 1 sigma", TDS),
    Param("bias", 0.0, "m", "switch-on bias, 1 sigma of its draw", "set per scene"),
    Param("max_range", 4000.0, "m", "no output beyond this slant range", TDS, 0.0, None, True),
    Param("beam_B", (0.0, 0.0, -1.0), "-", "beam direction, body frame", "one beam along body -z"),
)


def slant_range(r_W: np.ndarray, d_W: np.ndarray, radius: float) -> float | None:
    """Distance along unit ``d_W`` from ``r_W`` to the sphere of ``radius`` [m], or None if the ray misses it."""
    rd = float(r_W @ d_W)
    c = float(r_W @ r_W) - radius * radius
    disc = rd * rd - c
    if disc < 0.0:
        return None
    s = -rd - math.sqrt(disc)
    return s if s >= 0.0 else None


class RadarAltimeter:
    """Slant range ``z = [rho_m]`` (1)."""

    key = "altimeter"

    def __init__(self, values: dict[str, Any], rng: np.random.Generator) -> None:
        self.values = dict(values)
        self.rate = float(values["rate"])
        self.rng = rng
        self.beam_B = np.array(values["beam_B"], dtype=float)
        self.bias = float(values["bias"]) * float(rng.standard_normal())
        self.dropouts = 0

    def measure(self, truth: Truth, dt: float) -> Measurement | None:
        n = float(self.rng.standard_normal())
        s = slant_range(truth.r_W, body_to_world(truth.q, self.beam_B), truth.planet_radius) \
            if truth.planet_radius > 0.0 else None
        if s is None or s > float(self.values["max_range"]):
            self.dropouts += 1
            return None
        sigma = math.hypot(float(self.values["noise_floor"]), float(self.values["noise_fraction"]) * s)
        return Measurement(self.key, truth.t, np.array([s + self.bias + sigma * n]), np.array([sigma]))
