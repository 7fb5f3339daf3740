"""Integrators, chosen by name (scene key ``integrator``, node parameter ``integrator``)."""
from __future__ import annotations

from typing import Callable

from lander_sim.integrators.base import Integrator
from lander_sim.integrators.verlet import VelocityVerlet

#: name -> factory. Each factory takes keyword options (e.g. ``renormalise``).
REGISTRY: dict[str, Callable[..., Integrator]] = {
    "verlet": VelocityVerlet,
}


def make(name: str, **options: object) -> Integrator:
    """Build an integrator by name; an unknown name raises ``ValueError`` listing the choices."""
    try:
        factory = REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown integrator {name!r}; choose one of: {', '.join(sorted(REGISTRY))}") from None
    return factory(**options)


__all__ = ["Integrator", "REGISTRY", "make"]
