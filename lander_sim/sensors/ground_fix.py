"""Ground-tracking fix: position and velocity from radiometric tracking, for orbit and entry.

Measurement model: ``z = [r_W + n_r, v_W + n_v]``, ``n_r ~ N(0, sigma_r^2 I)``,
``n_v ~ N(0, sigma_v^2 I)``, world frame, at a low rate. It stands for the orbit determination of
the Deep Space Network's two-way Doppler and ranging, uplinked to the vehicle: knowledge of the
order of a kilometre in position and a metre per second in velocity at Mars (Martin-Mur et al.,
"Mars Science Laboratory Interplanetary Navigation", Journal of Spacecraft and Rockets 51(4), 2014,
reports entry-state knowledge within a few hundred metres after the last update; the defaults
here take the looser kilometre of an orbiter's routine solution). One fix every ten seconds is
faster than the real uplink, so a minute-long simulated flight sees several.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .base import Measurement, Truth
from .params import Param

DSN = "DSN orbit determination (Martin-Mur et al. 2014), order of magnitude"

PARAMS = (
    Param("rate", 0.1, "Hz", "output rate", "one fix per 10 s", 0.0, None, True),
    Param("position_noise", 1000.0, "m", "position error per world axis, 1 sigma", DSN),
    Param("velocity_noise", 1.0, "m/s", "velocity error per world axis, 1 sigma", DSN),
)


class GroundFix:
    """``z = [r_W (3), v_W (3)]`` with their noise."""

    key = "ground_fix"

    def __init__(self, values: dict[str, Any], rng: np.random.Generator) -> None:
        self.values = dict(values)
        self.rate = float(values["rate"])
        self.rng = rng
        self.dropouts = 0

    def measure(self, truth: Truth, dt: float) -> Measurement | None:
        sr, sv = float(self.values["position_noise"]), float(self.values["velocity_noise"])
        n = self.rng.standard_normal(6)
        z = np.concatenate((truth.r_W + sr * n[0:3], truth.v_W + sv * n[3:6]))
        return Measurement(self.key, truth.t, z, np.array([sr] * 3 + [sv] * 3))
