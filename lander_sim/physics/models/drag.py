"""The scene's drag section (``models.drag``): which drag model, and its parameters.

``kind: sphere`` is :class:`~lander_sim.physics.models.drag_sphere.SphereDrag` (the original
program's), ``kind: mesh`` is :class:`~lander_sim.physics.models.drag_mesh.MeshDrag` over a sphere
mesh scaled by the vehicle's size. Both need the atmosphere.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.base import BuildContext, Built, ModelEntry, needs_air
from lander_sim.physics.models.drag_mesh import MeshDrag, sphere_mesh
from lander_sim.physics.models.drag_sphere import SphereDrag
from lander_sim.yaml_file import Reader

_SPHERE_KEYS = {"kind", "cd", "area"}
_MESH_KEYS = {"kind", "radius", "centre_B", "n_lat", "n_lon", "skin_friction"}


@dataclass(frozen=True)
class DragConfig:
    """``kind``: ``sphere`` (``cd``, ``area`` [m^2]) or ``mesh`` (a sphere mesh of ``radius``
    vehicle sizes centred at ``centre_B`` [m, body frame], ``n_lat`` x ``n_lon`` elements,
    ``skin_friction`` coefficient)."""

    kind: str
    cd: float = c.SPHERE_DRAG_COEFFICIENT
    area: float = c.SPHERE_DRAG_AREA
    radius: float = c.LANDER_SIZE
    centre_B: tuple[float, float, float] = (0.0, 0.0, 0.0)
    n_lat: int = 12
    n_lon: int = 24
    skin_friction: float = 0.005


def parse(rd: Reader, node: object, path: str) -> DragConfig:
    d = rd.mapping(node, path, _SPHERE_KEYS | _MESH_KEYS, ("kind",))
    kind = rd.choice(d["kind"], f"{path}.kind", ("sphere", "mesh"))
    rd.mapping(d, path, _SPHERE_KEYS if kind == "sphere" else _MESH_KEYS)
    kw: dict[str, Any] = {}
    for k in ("cd", "area", "radius", "skin_friction"):
        if k in d:
            kw[k] = rd.number(d[k], f"{path}.{k}", 0.0)
    for k in ("n_lat", "n_lon"):
        if k in d:
            kw[k] = rd.integer(d[k], f"{path}.{k}", 2)
    if "centre_B" in d:
        kw["centre_B"] = rd.vector3(d["centre_B"], f"{path}.centre_B")
    return DragConfig(kind=kind, **kw)


def build(cfg: DragConfig, ctx: BuildContext) -> Built:
    if cfg.kind == "sphere":
        return Built(forces=(SphereDrag(cd=cfg.cd, area=cfg.area),))
    c_B, n_B, areas = sphere_mesh(cfg.radius * ctx.vehicle.size, np.array(cfg.centre_B), cfg.n_lat, cfg.n_lon)
    return Built(forces=(MeshDrag(c_B, n_B, areas, skin_friction=cfg.skin_friction),))


ENTRY = ModelEntry("drag", parse, build, needs_air)
