"""Integrators, chosen by name (scene key ``integrator``, node parameter ``integrator``).

=====================  =====  ==========================================================
name                   order  method
=====================  =====  ==========================================================
``verlet``             2      velocity Verlet, seed 1 section 5 (the reference scheme)
``symplectic-euler``   1      semi-implicit Euler (kick, then drift with the new rates)
``rk4``                4      classical Runge-Kutta on the first-order form
``adaptive``           5      Dormand-Prince 5(4), ``rtol``/``atol`` bound the local error per
                              step or (``error_control="global"``) the global error of a call
``geometric``          2      DLM rotor splitting + exponential map (|q| = 1 exactly)
``dop853``             8      Dormand-Prince 8(5,3) as scipy's ``solve_ivp``, local error control
=====================  =====  ==========================================================

``verlet``, RK4, ``adaptive``, ``geometric`` and ``dop853`` step a model that has a compiled form
(:func:`lander_sim.fast.rk_kernels.compiled_model`: the standard lander models and the seed-1
rigid bodies, quaternion or Euler-angle attitude; ``geometric`` quaternion only) in numba; option
``compiled=False`` keeps the numpy code (for ``dop853``: scipy), the reference they are tested against.

All advance translation and rotation together, in quaternion or (except ``geometric``)
ZXZ Euler-angle mode (eq 5-7 of the dynamics reference).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable

from lander_sim.integrators.adaptive import AdaptiveDormandPrince
from lander_sim.integrators.base import Integrator, IntegratorError, check_dt
from lander_sim.integrators.dop853 import DOP853
from lander_sim.integrators.geometric import Geometric
from lander_sim.integrators.rk4 import RK4
from lander_sim.integrators.symplectic_euler import SymplecticEuler
from lander_sim.integrators.verlet import VelocityVerlet

#: name -> factory. Each factory takes keyword options (e.g. ``renormalise``).
REGISTRY: dict[str, Callable[..., Integrator]] = {
    "verlet": VelocityVerlet,
    "symplectic-euler": SymplecticEuler,
    "rk4": RK4,
    "adaptive": AdaptiveDormandPrince,
    "geometric": Geometric,
    "dop853": DOP853,
}


def options_of(name: str) -> tuple[str, ...]:
    """The keyword options integrator ``name`` accepts (public dataclass fields)."""
    factory = _factory(name)
    return tuple(
        f.name
        for f in dataclasses.fields(factory)  # type: ignore[arg-type]  # every registered factory is a dataclass
        if f.init and not f.name.startswith("_") and f.name not in ("name", "order", "accepted", "rejected", "last_error", "max_error")
    )


def _factory(name: str) -> Callable[..., Integrator]:
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise IntegratorError(f"unknown integrator {name!r}; choose one of: {', '.join(sorted(REGISTRY))}") from None


def make(name: str, **options: object) -> Integrator:
    """Build an integrator by name.

    Raises :class:`IntegratorError` (a ``ValueError``) for an unknown name (listing the choices)
    or an option the method does not have (listing its options).
    """
    factory = _factory(name)
    allowed = options_of(name)
    for key in options:
        if key not in allowed:
            raise IntegratorError(
                f"integrator {name!r} has no option {key!r}; its options are: {', '.join(allowed) or '(none)'}"
            )
    return factory(**options)


__all__ = ["Integrator", "IntegratorError", "REGISTRY", "check_dt", "make", "options_of"]
