"""A constant world-frame force acting at a body point (the weighted gimballed rotor of seed 1)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lander_sim.physics.models.base import BuildContext, Built, EvalContext, ModelEntry
from lander_sim.yaml_file import Reader


@dataclass
class ConstantForce:
    """``F_W`` constant, applied at ``point_B``: body torque ``point_B x (R F_W)``.

    With a fixed pivot ``point_B`` is measured from the pivot (the seed: ``F = [0, 0, -10]``
    at ``r = [0, 0, 1]``); the force also acts on the centre of mass when translation is on.

    Attributes
    ----------
    force_W : ndarray (3,)
        Force, world frame [N].
    point_B : ndarray (3,)
        Point of action, body frame [m].
    """

    force_W: np.ndarray
    point_B: np.ndarray
    name: str = "constant_force"
    calls: int = 0

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        force_W += self.force_W
        torque_B += np.cross(self.point_B, ctx.R @ self.force_W)

    def potential(self, r_W: np.ndarray, R: np.ndarray, mass: float) -> float:
        """Potential ``-F_W . (r_W + R^T point_B)`` [J] of a constant force (zero at the origin)."""
        return -float(self.force_W @ (r_W + R.T @ self.point_B))


@dataclass(frozen=True)
class ConstantForceConfig:
    """Scene section ``models.constant_force``: ``force_W`` [N, world frame] at ``point_B`` [m, body frame]."""

    force_W: tuple[float, float, float]
    point_B: tuple[float, float, float]


def parse(rd: Reader, node: object, path: str) -> ConstantForceConfig:
    f = rd.mapping(node, path, {"force_W", "point_B"}, ("force_W", "point_B"))
    return ConstantForceConfig(rd.vector3(f["force_W"], f"{path}.force_W"), rd.vector3(f["point_B"], f"{path}.point_B"))


def build(cfg: ConstantForceConfig, ctx: BuildContext) -> Built:
    return Built(forces=(ConstantForce(np.array(cfg.force_W, dtype=float), np.array(cfg.point_B, dtype=float)),))


ENTRY = ModelEntry("constant_force", parse, build)
