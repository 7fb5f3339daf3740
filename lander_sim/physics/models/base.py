"""What every force/torque model sees and provides.

A model is switched on by a scene and then lives in the evaluation loop of
:class:`lander_sim.physics.dynamics.LanderDynamics`; a model that is off is
simply not in that loop, so it costs nothing.

Each evaluation fills one :class:`EvalContext` (reused, never reallocated) with
the quantities several models need, then calls every model's ``add``, which
*adds* its contribution to three accumulators: ``force_W`` (world frame, acting
at the centre of mass), ``force_B`` (body frame, at the centre of mass) and
``torque_B`` (body frame, about the centre of mass or the fixed pivot).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from lander_sim.physics.models.atmosphere import Atmosphere
    from lander_sim.physics.models.ground import Ground
    from lander_sim.physics.vehicle import Vehicle
    from lander_sim.yaml_file import Reader


@dataclass
class Inputs:
    """Commands that are piecewise constant over a step (set between steps only).

    Attributes
    ----------
    throttles : ndarray (N,)
        Throttle of each thruster in [0, 1].
    wind_W : ndarray (3,)
        Wind velocity, world frame [m/s].
    """

    throttles: np.ndarray
    wind_W: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class EvalContext:
    """Per-evaluation quantities shared by the models (overwritten each evaluation).

    Attributes
    ----------
    y : ndarray (14,)
        The state being evaluated (read only).
    R : ndarray (3, 3)
        World-to-body rotation matrix (eq 3 or eq 13).
    mass : float
        Current total mass [kg].
    altitude : float
        ``|r_W| - R_mars`` [m] (0 in scenes without a planet).
    rho : float
        Air density at the current altitude [kg/m^3] (0 without an atmosphere).
    inputs : Inputs
        Throttles and wind.
    """

    inputs: Inputs
    y: np.ndarray = field(default_factory=lambda: np.zeros(14))
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    mass: float = 0.0
    altitude: float = 0.0
    rho: float = 0.0


class ForceModel(Protocol):
    """A force and/or torque contribution."""

    #: Scene key of the model (``gravity``, ``drag``, ...).
    name: str
    #: Number of ``add`` calls (shows in tests that a switched-off model is never evaluated).
    calls: int

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        """Add this model's force (world or body frame) and body torque to the accumulators."""
        ...


# --- a model as a scene switches it on (the table: lander_sim.physics.models.table) ----------


@dataclass(frozen=True)
class BuildContext:
    """What a model's ``build`` may use besides its own config: the vehicle, and the planet radius
    [m] set by the gravity model (0 without a planet; models are built in the table's order)."""

    vehicle: Vehicle
    planet_radius: float = 0.0


@dataclass(frozen=True)
class Built:
    """What one model adds to a simulation: force/torque models for the evaluation loop, the
    atmosphere (density for the drag models), the planet radius, the ground (touchdown)."""

    forces: tuple[ForceModel, ...] = ()
    atmosphere: Atmosphere | None = None
    planet_radius: float | None = None
    ground: Ground | None = None


@dataclass(frozen=True)
class ModelEntry:
    """One row of the models table: the scene key under ``models:``, and the model module's own

    * ``parse(reader, node, path) -> config``: the section, validated (errors name ``path``);
    * ``build(config, context) -> Built``: the model objects;
    * ``needs(configs) -> str | None``: why the model cannot be on with the other models switched
      on (``configs``: key -> config of every model on), or None.
    """

    key: str
    parse: Callable[[Reader, Any, str], Any]
    build: Callable[[Any, BuildContext], Built]
    needs: Callable[[Mapping[str, Any]], str | None] = lambda _on: None


def needs_planet(on: Mapping[str, Any]) -> str | None:
    """For models that need a planet (altitude above its surface): inverse-square gravity."""
    g = on.get("gravity")
    return None if getattr(g, "kind", None) == "inverse-square" else "needs a planet: expected models.gravity.kind: inverse-square"


def needs_air(on: Mapping[str, Any]) -> str | None:
    """For models that need air density: the atmosphere."""
    return None if "atmosphere" in on else "needs air: expected models.atmosphere to be switched on"
