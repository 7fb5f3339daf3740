"""Inertial measurement unit: gyroscope (body rate) and accelerometer (specific force), body frame.

Measurement model (Groves 2013, eq 4.14 and 4.16, without scale factor and misalignment)::

    omega_m = omega_B + b_g + n_g,      f_m = f_B + b_a + n_a,      f_B = R_BW (a_W - g_W)

``f_B`` is the specific force: the non-gravitational force per unit mass (thrust, drag, the
ground's reaction). Gravity pulls the proof mass as it pulls the case, so the accelerometer reads 0
in free fall and ``+g`` along the local up at rest on the ground or in a balanced hover. ``b_g``,
``b_a`` are random-walk biases (:class:`.base.RandomWalkBias`), ``n_g``, ``n_a`` white noise of
density ``N`` whose per-sample deviation is ``N / sqrt(dt)`` for an output averaged over the
interval ``dt`` since the previous sample (a delta-angle / delta-velocity unit divided by its
interval).

Defaults: the Litton (Northrop Grumman) LN-200 fibre-optic IMU, which flew on the Mars
Exploration Rovers' and Mars Science Laboratory's descent stages (the LN-200S) and on Mars 2020.
The LN-200 datasheet gives the gyro bias repeatability 1 deg/h, angle random walk
0.07 deg/sqrt(h), the accelerometer bias repeatability 300 micro-g and white noise 50 micro-g/sqrt(Hz)
(1 sigma), and data rates up to 400 Hz. The in-run bias walk densities are not on the datasheet:
they are set so the bias moves about a tenth of its repeatability per hour (an estimate, marked as
such in the table).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .base import Measurement, RandomWalkBias, Truth, white_sigma
from .params import Param

G0 = 9.80665  #: standard gravity [m/s^2], the unit of accelerometer datasheets (micro-g)
DEG_PER_HOUR = math.pi / 180.0 / 3600.0  #: [rad/s]

LN200 = "LN-200 datasheet"
ESTIMATE = "estimate: 0.1 x the repeatability per hour"

PARAMS = (
    Param("rate", 400.0, "Hz", "highest output rate (at most one sample per simulation step)", LN200, 0.0, None, True),
    Param("gyro_noise_density", 0.07 * math.pi / 180.0 / 60.0, "rad/s/sqrt(Hz)",
          "gyro white noise (angle random walk 0.07 deg/sqrt(h))", LN200),
    Param("gyro_bias", 1.0 * DEG_PER_HOUR, "rad/s", "gyro switch-on bias, 1 sigma per axis (1 deg/h)", LN200),
    Param("gyro_bias_walk", 0.1 * DEG_PER_HOUR / 60.0, "rad/s/sqrt(s)", "gyro bias instability as a random walk", ESTIMATE),
    Param("accel_noise_density", 50e-6 * G0, "m/s^2/sqrt(Hz)", "accelerometer white noise (50 micro-g/sqrt(Hz))", LN200),
    Param("accel_bias", 300e-6 * G0, "m/s^2", "accelerometer switch-on bias, 1 sigma per axis (300 micro-g)", LN200),
    Param("accel_bias_walk", 30e-6 * G0 / 60.0, "m/s^2/sqrt(s)", "accelerometer bias instability as a random walk",
          ESTIMATE),
)


class IMU:
    """Gyro and accelerometer; :meth:`measure` gives ``z = [omega_m (3), f_m (3)]``."""

    key = "imu"

    def __init__(self, values: dict[str, Any], rng: np.random.Generator) -> None:
        self.values = dict(values)
        self.rate = float(values["rate"])
        self.rng = rng
        # fixed draw order: gyro bias, accelerometer bias, then per sample gyro walk, accel walk, noise
        self.gyro_bias = RandomWalkBias(3, float(values["gyro_bias"]), float(values["gyro_bias_walk"]), rng)
        self.accel_bias = RandomWalkBias(3, float(values["accel_bias"]), float(values["accel_bias_walk"]), rng)
        self.dropouts = 0

    def measure(self, truth: Truth, dt: float) -> Measurement | None:
        """One sample averaged over the ``dt`` [s] since the previous one (``dt > 0``)."""
        bg = self.gyro_bias.advance(dt)
        ba = self.accel_bias.advance(dt)
        sg = white_sigma(float(self.values["gyro_noise_density"]), dt)
        sa = white_sigma(float(self.values["accel_noise_density"]), dt)
        n = self.rng.standard_normal(6)
        z = np.concatenate((truth.omega_B + bg + sg * n[0:3], truth.f_B + ba + sa * n[3:6]))
        return Measurement(self.key, truth.t, z, np.array([sg] * 3 + [sa] * 3))
