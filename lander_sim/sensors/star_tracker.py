"""Star tracker: the attitude, from star patterns; it loses its stars above a body rate.

Measurement model: ``q_m = q x dq(n)``, ``dq(n) = (cos(|n|/2), sin(|n|/2) n/|n|)``, with the body-frame
error ``n = b + n_w``: a constant bias ``b`` (``bias``, a fixed misalignment, one draw per axis at
switch-on) and white noise ``n_w ~ N(0, sigma^2 I)`` per sample. ``q`` maps world to body
(:mod:`lander_sim.physics.rotation`), so ``q x dq`` is the true attitude turned by ``n`` about body
axes: the error a filter's multiplicative update estimates. No output while
``|omega_B| > max_rate`` (the stars smear across the detector and the tracker loses lock).

Defaults: typical of flight star trackers (e.g. Jena-Optronik ASTRO APS, Sodern HYDRA): a few
arcseconds across the boresight and several times that about it, taken here as 30 arcsec on every
axis; outputs at 5 Hz (data sheets give 4-16 Hz); tracking up to about 2 deg/s. The Mars landers
carried star scanners on their cruise stages, dropped before entry: the tracker suits the orbit and
de-orbit scenes.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_sim.physics.rotation import quat_mult

from .base import Measurement, Truth
from .params import Param

ARCSEC = math.pi / 180.0 / 3600.0
TYPICAL = "typical flight star tracker data sheets"

PARAMS = (
    Param("rate", 5.0, "Hz", "output rate", TYPICAL, 0.0, None, True),
    Param("noise", 30.0 * ARCSEC, "rad", "white noise per body axis, 1 sigma (30 arcsec)", TYPICAL),
    Param("bias", 0.0, "rad", "fixed misalignment per body axis, 1 sigma of its switch-on draw", "set per scene"),
    Param("max_rate", 2.0 * math.pi / 180.0, "rad/s", "no output above this body rate (2 deg/s)", TYPICAL, 0.0, None, True),
)


def rotation_quat(n: np.ndarray) -> np.ndarray:
    """``dq(n)``: the unit quaternion of a rotation by ``|n|`` [rad] about ``n`` (eq 9 of the dynamics reference)."""
    a = math.sqrt(float(n @ n))
    if a < 1e-12:
        return np.array([1.0, 0.5 * n[0], 0.5 * n[1], 0.5 * n[2]]) / math.sqrt(1.0 + 0.25 * a * a)
    k = math.sin(0.5 * a) / a
    return np.array([math.cos(0.5 * a), k * n[0], k * n[1], k * n[2]])


class StarTracker:
    """Attitude quaternion ``z = q_m`` (4), ``sigma`` the per-axis angle noise (3)."""

    key = "star_tracker"

    def __init__(self, values: dict[str, Any], rng: np.random.Generator) -> None:
        self.values = dict(values)
        self.rate = float(values["rate"])
        self.rng = rng
        self.bias = float(values["bias"]) * rng.standard_normal(3)
        self.dropouts = 0

    def measure(self, truth: Truth, dt: float) -> Measurement | None:
        n = self.rng.standard_normal(3)  # drawn even on a dropout: the noise sequence is the time's, not the lock's
        w = truth.omega_B
        if math.sqrt(float(w @ w)) > float(self.values["max_rate"]):
            self.dropouts += 1
            return None
        s = float(self.values["noise"])
        q = quat_mult(truth.q, rotation_quat(self.bias + s * n))
        if q[0] < 0.0:
            q = -q
        return Measurement(self.key, truth.t, q, np.full(3, s))
