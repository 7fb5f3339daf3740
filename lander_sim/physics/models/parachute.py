"""Parachute of the extended program: drag at a body point, lost when overloaded or deployed too fast."""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import BuildContext, Built, EvalContext, ModelEntry, needs_air
from lander_sim.physics.rotation import cross3
from lander_sim.yaml_file import Reader


class ChuteStatus(enum.Enum):
    NOT_DEPLOYED = "not_deployed"
    DEPLOYED = "deployed"
    LOST = "lost"


@dataclass
class Parachute:
    """Drag ``F_B = 1/2 rho Cd (pi r^2) |W| W`` applied at ``attach_B``; torque ``attach_B x F_B``.

    ``W = R (wind_W - v_W) - omega_B x attach_B`` is the air velocity relative to the
    attachment point, body frame. Only a deployed chute pulls. It is lost (for good)
    when its drag exceeds ``max_drag`` or when deployed faster than ``max_speed``
    inside the atmosphere; :class:`lander_sim.simulation.Simulation` applies those
    rules between steps through :meth:`drag_magnitude` and :meth:`deploy`.

    Attributes
    ----------
    radius : float
        Canopy radius [m] (3).
    cd : float
        Drag coefficient (2.0).
    attach_B : ndarray (3,)
        Attachment point relative to the centre of mass, body frame [m] (``(0, 0, L/2)``).
    max_drag : float
        [N] (20 kN).
    max_speed : float
        [m/s] (500).
    status : ChuteStatus
        Model state (part of snapshots).
    """

    radius: float = c.PARACHUTE_RADIUS
    cd: float = c.PARACHUTE_DRAG_COEFFICIENT
    attach_B: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.5 * c.LANDER_SIZE]))
    max_drag: float = c.PARACHUTE_MAX_DRAG
    max_speed: float = c.PARACHUTE_MAX_SPEED
    status: ChuteStatus = ChuteStatus.NOT_DEPLOYED
    name: str = "parachute"
    calls: int = 0

    def __post_init__(self) -> None:
        self._k = 0.5 * self.cd * math.pi * self.radius**2

    def _force_B(self, ctx: EvalContext) -> np.ndarray:
        y = ctx.y
        W = ctx.R @ (ctx.inputs.wind_W - y[3:6]) - cross3(y[10:13], self.attach_B)
        F_B: np.ndarray = (self._k * ctx.rho * math.sqrt(float(W @ W))) * W
        return F_B

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        if self.status is not ChuteStatus.DEPLOYED or ctx.rho == 0.0:
            return
        F = self._force_B(ctx)
        force_B += F
        torque_B += cross3(self.attach_B, F)

    def drag_magnitude(self, ctx: EvalContext) -> float:
        """Drag the canopy would pull with in this context [N] (whether deployed or not)."""
        return float(np.linalg.norm(self._force_B(ctx))) if ctx.rho > 0.0 else 0.0

    def deploy(self, speed: float, inside_atmosphere: bool) -> ChuteStatus:
        """Deploy if still packed; too fast inside the atmosphere destroys it. Returns the new status."""
        if self.status is ChuteStatus.NOT_DEPLOYED:
            too_fast = inside_atmosphere and speed > self.max_speed
            self.status = ChuteStatus.LOST if too_fast else ChuteStatus.DEPLOYED
        return self.status


@dataclass(frozen=True)
class ParachuteConfig:
    """Scene section ``models.parachute``: canopy radius [m], drag coefficient, attachment point
    [m, body frame; None: the top of the body, ``(0, 0, L/2)``], drag [N] and speed [m/s] limits."""

    radius: float = c.PARACHUTE_RADIUS
    cd: float = c.PARACHUTE_DRAG_COEFFICIENT
    attach_B: tuple[float, float, float] | None = None
    max_drag: float = c.PARACHUTE_MAX_DRAG
    max_speed: float = c.PARACHUTE_MAX_SPEED


def parse(rd: Reader, node: object, path: str) -> ParachuteConfig:
    p = rd.mapping(node, path, {"radius", "cd", "attach_B", "max_drag", "max_speed"})
    kw: dict[str, Any] = {k: rd.number(v, f"{path}.{k}", 0.0, strict_lo=True) for k, v in p.items() if k != "attach_B"}
    if "attach_B" in p:
        kw["attach_B"] = rd.vector3(p["attach_B"], f"{path}.attach_B")
    return ParachuteConfig(**kw)


def build(cfg: ParachuteConfig, ctx: BuildContext) -> Built:
    attach = np.array(cfg.attach_B if cfg.attach_B is not None else (0.0, 0.0, 0.5 * ctx.vehicle.size))
    return Built(forces=(Parachute(radius=cfg.radius, cd=cfg.cd, attach_B=attach, max_drag=cfg.max_drag,
                                   max_speed=cfg.max_speed),))


ENTRY = ModelEntry("parachute", parse, build, needs_air)
