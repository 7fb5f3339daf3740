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


class Air(Protocol):
    """What an atmosphere provides (:class:`lander_sim.physics.models.atmosphere.Atmosphere`):
    the density the drag models and the parachute see, and its exponential law's parameters
    (``rho = rho0 exp(-h / H)`` below the exosphere, zero above), which the compiled kernels
    (:mod:`lander_sim.fast`) evaluate themselves."""

    @property
    def surface_density(self) -> float:
        """``rho0`` [kg/m^3]."""
        ...

    @property
    def scale_height(self) -> float:
        """``H`` [m]."""
        ...

    @property
    def exosphere(self) -> float:
        """Altitude above which the density is zero [m]."""
        ...

    def density(self, altitude: float) -> float:
        """Air density [kg/m^3] at ``altitude`` [m] above the surface."""
        ...


#: Touchdown classes, best first.
SAFE, HARD, CRASH = "safe", "hard", "crash"


@dataclass(frozen=True)
class Touchdown:
    """Where and how the lander met the ground.

    Attributes
    ----------
    fraction : float
        Fraction ``s`` of the last step at which the impact happened, in [0, 1].
    descent_rate : float
        ``-v . r_hat`` at impact [m/s] (positive downwards).
    ground_speed : float
        Horizontal speed at impact [m/s].
    crashed : bool
        True when the touchdown is a crash (``classification == "crash"``).
    tilt : float
        Angle between the body z axis and the local vertical at impact [rad].
    classification : str
        ``safe``, ``hard`` or ``crash`` (:meth:`TouchdownLimits.classify`).
    """

    fraction: float
    descent_rate: float
    ground_speed: float
    crashed: bool
    tilt: float = 0.0
    classification: str = SAFE


class Surface(Protocol):
    """What a ground provides (:class:`lander_sim.physics.models.ground.Ground`): where the
    lander touches and how the touchdown is classified."""

    @property
    def contact_radius(self) -> float:
        """Centre-of-mass distance from the planet's centre at which the lander touches [m]."""
        ...

    def below(self, r_W: np.ndarray) -> bool:
        """True when the centre of mass at ``r_W`` [m] is inside the contact radius."""
        ...

    def impact_fraction(self, r0_W: np.ndarray, r1_W: np.ndarray) -> float:
        """Fraction in [0, 1] of the straight step from ``r0_W`` to ``r1_W`` at which it touches."""
        ...

    def classify(self, fraction: float, r_W: np.ndarray, v_W: np.ndarray, z_B_W: np.ndarray | None = None) -> Touchdown:
        """The touchdown at the interpolated impact state (``z_B_W``: body z axis, world frame)."""
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
    atmosphere: Air | None = None
    planet_radius: float | None = None
    ground: Surface | None = None


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
