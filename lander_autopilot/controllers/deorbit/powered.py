"""The powered descent as a part of the de-orbit mission: one small interface, two implementations.

The mission (:class:`.mission.DeorbitController`) flies every phase with the scheduled descent law
(:class:`.descent.DescentToAltitude`); in ``powered-descent`` it then hands the period to its
powered-descent part, which returns the period's output: the scheduled law's as it is
(:class:`ScheduledDescent`, controller ``deorbit``) or the MPC's (:class:`.mpc.MpcDescent`,
controller ``deorbit-mpc``). The part reads the mission through :class:`Mission`'s public
members only. The phase machine decides when the powered descent ends (the fall stopped in the
hover band), whichever part flies it.
"""
from __future__ import annotations

from typing import Protocol

from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..base import ControlOutput, Demand
from ..calibration import AirFit, ThrustCalibration
from .descent import DescentToAltitude
from .phases import Phase


class Mission(Protocol):
    """What a powered-descent part may read of the mission flying it (and the note it may log)."""

    @property
    def vehicle(self) -> Vehicle: ...

    @property
    def phase(self) -> Phase: ...

    @property
    def chute_open(self) -> bool: ...

    @property
    def air(self) -> AirFit | None: ...

    @property
    def thrust_calibration(self) -> ThrustCalibration: ...

    @property
    def descent(self) -> DescentToAltitude: ...

    def note(self, t: float, why: str) -> None: ...


class PoweredDescent(Protocol):
    """A powered-descent part: ``fly`` gives the period's output from the scheduled law's
    (``scheduled``, already flown this period); ``reset`` forgets the flight; ``diagnostics`` its
    figures (SI units) for the node's ``/diagnostics`` and a sweep's row."""

    def reset(self) -> None: ...

    def fly(self, t: float, state: StateView, demand: Demand, mission: Mission,
            scheduled: ControlOutput) -> ControlOutput: ...

    def diagnostics(self) -> dict[str, float]: ...


class ScheduledDescent:
    """The scheduled law flies the powered descent: its output as it is (controller ``deorbit``)."""

    def reset(self) -> None:
        """Nothing to forget: the scheduled law is the mission's own descent law."""

    def fly(self, t: float, state: StateView, demand: Demand, mission: Mission,
            scheduled: ControlOutput) -> ControlOutput:
        return scheduled

    def diagnostics(self) -> dict[str, float]:
        return {}
