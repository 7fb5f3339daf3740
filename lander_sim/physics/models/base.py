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

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


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
