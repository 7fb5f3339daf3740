"""Doppler velocimeter: the velocity over the ground in the body frame, below an altitude.

Measurement model: ``v_m = R_BW v_W + b + n``, ``n ~ N(0, sigma^2 I)``,
``sigma^2 = sigma_0^2 + (k |v|)^2`` (a floor and a fraction of the speed), ``b`` a switch-on bias per
axis. The planet does not turn in the simulator, so ``v_W`` is the velocity over the ground. No
output above ``max_altitude`` (the radar's echo is too weak) or at or below the ground.

Defaults: after the Mars Science Laboratory's Terminal Descent Sensor, whose six beams' line-of-sight
velocities solve for the three-axis velocity at 20 Hz from about 4 km down, with errors of the order
of 1 % of the speed (Pollard and Sadowy, IEEE Aerospace Conference, 2005); the floor is an estimate.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_sim.physics.rotation import world_to_body

from .base import Measurement, Truth
from .params import Param

TDS = "MSL Terminal Descent Sensor (Pollard and Sadowy 2005)"

PARAMS = (
    Param("rate", 20.0, "Hz", "output rate", TDS, 0.0, None, True),
    Param("noise_floor", 0.02, "m/s", "velocity noise floor per axis, 1 sigma", "estimate"),
    Param("noise_fraction", 0.01, "-", "velocity noise as a fraction of the speed, 1 sigma", TDS),
    Param("bias", 0.0, "m/s", "switch-on bias per axis, 1 sigma of its draw", "set per scene"),
    Param("max_altitude", 4000.0, "m", "no output above this altitude", TDS, 0.0, None, True),
)


class DopplerVelocimeter:
    """Body-frame velocity ``z = v_m`` (3)."""

    key = "doppler"

    def __init__(self, values: dict[str, Any], rng: np.random.Generator) -> None:
        self.values = dict(values)
        self.rate = float(values["rate"])
        self.rng = rng
        self.bias = float(values["bias"]) * rng.standard_normal(3)
        self.dropouts = 0

    def measure(self, truth: Truth, dt: float) -> Measurement | None:
        n = self.rng.standard_normal(3)
        h = math.sqrt(float(truth.r_W @ truth.r_W)) - truth.planet_radius
        if truth.planet_radius <= 0.0 or not 0.0 < h <= float(self.values["max_altitude"]):
            self.dropouts += 1
            return None
        speed = math.sqrt(float(truth.v_W @ truth.v_W))
        sigma = math.hypot(float(self.values["noise_floor"]), float(self.values["noise_fraction"]) * speed)
        z = world_to_body(truth.q, truth.v_W) + self.bias + sigma * n
        return Measurement(self.key, truth.t, z, np.full(3, sigma))
