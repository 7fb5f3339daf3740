"""The active controller, its demand and the autopilot's bookkeeping, swapped whole.

Plain Python (no rclpy): the node calls :meth:`ControllerSlot.step` from its state callback and
:meth:`ControllerSlot.swap` from its parameter callback, both in one executor thread, so a swap
falls between two control steps. A new controller is built and validated completely
(:func:`build_choice`) before the swap; if building fails the running one keeps flying.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_autopilot.controllers import ControlOutput, Demand, make_controller
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle
from lander_sim.scenes import load_scene

from .config import ConfigError


@dataclass(frozen=True)
class ControllerChoice:
    """A built, ready-to-fly controller and what it was built from."""

    scene: str
    vehicle: Vehicle
    name: str
    params: Mapping[str, Any]
    controller: Any  # a Controller, or a third-party object with name/reset/update


def build_choice(scene: str, controller: str, params: Mapping[str, Any]) -> ControllerChoice:
    """Load ``scene``'s vehicle and build ``controller`` with ``params`` for it.

    Raises :class:`ValueError` (``SceneError``, ``ControllerError`` or :class:`ConfigError`) with
    a message naming the scene, the controller or the parameter. Anything else a third-party
    plug-in raises while building is wrapped into a :class:`ConfigError` too: a broken plug-in must
    not take the node down.
    """
    vehicle = load_scene(scene).vehicle
    try:
        ctrl = make_controller(controller, vehicle, **dict(params))
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001 - third-party factories may raise anything
        raise ConfigError(f"controller {controller!r} could not be built: {type(exc).__name__}: {exc}") from None
    return ControllerChoice(scene, vehicle, controller, dict(params), ctrl)


class OutputError(ValueError):
    """A controller returned throttles that must not be sent (wrong length, NaN, outside [0, 1])."""


class ControllerSlot:
    """The flying controller plus its demand, step count and error bookkeeping.

    Attributes
    ----------
    choice : ControllerChoice
        The active controller.
    demand : Demand
        What it is asked to hold (altitude [m] above the surface, attitude, rates).
    steps : int
        Control updates since the active controller was installed.
    rejected : int
        Inputs refused since start (bad demands, bad states, refused parameter changes).
    last_error : str
        The latest refusal or failure ("" if none).
    saturated : bool, throttles : ndarray
        Of the last command sent.
    last_sequence : int
        Sequence of the last state answered (0: none yet).
    mode : str
        The active controller's mode after the last step ("" for laws without modes).
    """

    def __init__(self, choice: ControllerChoice, demand: Demand) -> None:
        self.choice = choice
        self.demand = demand
        self.steps = 0
        self.rejected = 0
        self.last_error = ""
        self.saturated = False
        self.throttles = np.zeros(choice.vehicle.n_thrusters)
        self.last_sequence = 0
        self.mode = ""
        choice.controller.reset()

    @property
    def name(self) -> str:
        return self.choice.name

    def swap(self, choice: ControllerChoice) -> ControllerChoice:
        """Install an already built controller (reset first); return the one it replaces."""
        choice.controller.reset()
        old, self.choice = self.choice, choice
        self.steps = 0
        self.mode = ""
        if len(self.throttles) != choice.vehicle.n_thrusters:
            self.throttles = np.zeros(choice.vehicle.n_thrusters)
        return old

    @staticmethod
    def check_demand_altitude(altitude: float) -> None:
        """Raise ``DemandError`` (naming the value) unless ``altitude`` is a valid demand [m]."""
        Demand(altitude=altitude)

    def set_demand_altitude(self, altitude: float) -> None:
        """Replace the demand altitude [m]; on ``DemandError`` the previous demand is kept."""
        self.demand = dataclasses.replace(self.demand, altitude=altitude)

    def set_demand_velocity(self, velocity: tuple[float, float] | None) -> None:
        """Replace the demand horizontal velocity (ENU ``(east, north)`` [m/s], None: none);
        raises ``DemandError`` and keeps the previous demand if it is invalid."""
        self.demand = dataclasses.replace(self.demand, velocity=velocity)

    def reject(self, reason: str) -> int:
        """Count one refused input and remember why; return the count."""
        self.rejected += 1
        self.last_error = reason
        return self.rejected

    def step(self, state: StateView, sequence: int) -> ControlOutput:
        """One control update on ``state`` (sequence ``sequence`` of the simulator's states).

        A sequence that does not increase means the simulator was reset or reloaded: the
        controller's memory (integrators) is cleared first. Raises :class:`OutputError` when the
        controller's throttles must not be sent; nothing is recorded as sent then.
        """
        ctrl = self.choice.controller
        if sequence <= self.last_sequence:
            ctrl.reset()
        self.last_sequence = sequence
        out = ctrl.update(state.t, state, self.demand)
        u = np.asarray(out.throttles, dtype=float)
        n = self.choice.vehicle.n_thrusters
        if u.shape != (n,) or not all(0.0 <= x <= 1.0 for x in u):  # also false for NaN
            raise OutputError(
                f"controller {self.name!r} returned throttles {u.tolist()} at t = {state.t} s: "
                f"expected {n} values in [0, 1]; nothing sent"
            )
        self.steps += 1
        self.saturated = bool(out.saturated)
        self.throttles = u
        self.mode = str(getattr(out, "mode", None) or "")
        return out

