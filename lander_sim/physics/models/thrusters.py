"""Thrusters: ``F_i = -d_i t_i T_max`` at ``p_i``, torque ``p_i x F_i`` (seed 1 task 2), fuel burn."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lander_sim.physics.models.base import BuildContext, Built, EvalContext, ModelEntry
from lander_sim.physics.vehicle import Vehicle
from lander_sim.yaml_file import Reader


@dataclass
class Thrusters:
    """All thrusters of a vehicle, body frame.

    Force and torque are linear in the throttles, so they are precomputed as
    ``(N, 3)`` matrices (``-d_i T_max`` and ``p_i x (-d_i T_max)``, zero rows for
    disabled thrusters) and each evaluation is two small matrix-vector products.
    No fuel, no thrust.
    """

    vehicle: Vehicle
    name: str = "thrusters"
    calls: int = 0
    _force: np.ndarray = field(init=False, repr=False)
    _torque: np.ndarray = field(init=False, repr=False)
    _burn: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        th = self.vehicle.thrusters
        on = np.array([1.0 if t.enabled else 0.0 for t in th]).reshape(-1, 1)
        F = np.array([-np.asarray(t.direction_B, float) * t.max_thrust for t in th]).reshape(-1, 3) * on
        P = np.array([np.asarray(t.position_B, float) for t in th]).reshape(-1, 3)
        self._force = F
        self._torque = np.cross(P, F).reshape(-1, 3)
        self._burn = np.array([t.fuel_rate for t in th]) * on.reshape(-1)

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        if ctx.y[13] <= 0.0:
            return
        t = ctx.inputs.throttles
        force_B += t @ self._force
        torque_B += t @ self._torque

    def fuel_rate(self, y: np.ndarray, throttles: np.ndarray) -> float:
        """Fuel mass rate [kg/s] (<= 0); zero with an empty tank."""
        if y[13] <= 0.0:
            return 0.0
        return -float(throttles @ self._burn)


@dataclass(frozen=True)
class ThrustersConfig:
    """Scene section ``models.thrusters``: no keys (the thrusters are the vehicle's)."""


def parse(rd: Reader, node: object, path: str) -> ThrustersConfig:
    rd.mapping(node, path, set())
    return ThrustersConfig()


def build(cfg: ThrustersConfig, ctx: BuildContext) -> Built:
    return Built(forces=(Thrusters(ctx.vehicle),))


ENTRY = ModelEntry("thrusters", parse, build)
