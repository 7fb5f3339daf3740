"""The de-orbit mission's phases as a pure state machine: named phases, named events, one table.

Plain Python, no state but the phase and its log. The mission (:class:`.mission.DeorbitController`)
measures each event's condition with the functions below and fires the event; the machine
answers the next phase from :data:`TRANSITIONS` (forward only) and refuses any other pair, so a
phase can never be skipped or re-entered by a flag left set (test/control/test_deorbit_phases.py
checks every pair)::

    deorbit-slew  --burn start reached-->        deorbit-burn
    deorbit-burn  --periapsis reached-->         coast
    coast         --atmosphere reached-->        entry
    entry         --chute opened-->              parachute
    entry, parachute --braking curve reached-->  powered-descent
    powered-descent  --fall stopped in the band--> hover
    hover         --land demanded-->             landing
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

from lander_sim.physics import constants as c


class Phase(str, enum.Enum):
    """Mission phases, in flight order."""

    SLEW = "deorbit-slew"
    BURN = "deorbit-burn"
    COAST = "coast"
    ENTRY = "entry"
    PARACHUTE = "parachute"
    POWERED = "powered-descent"
    HOVER = "hover"
    LANDING = "landing"


#: Phases in which the descent law (landing law ending at the demand altitude) flies.
DESCENT_PHASES = (Phase.ENTRY, Phase.PARACHUTE, Phase.POWERED)

#: Phases that need the de-orbit plan: a flight started inside the atmosphere begins after them.
ORBIT_PHASES = (Phase.SLEW, Phase.BURN, Phase.COAST)


class Event(str, enum.Enum):
    """What moves the mission on (each with its condition below)."""

    BURN_START = "burn start reached"  # burn_due
    PERIAPSIS = "periapsis reached"  # periapsis_reached
    ATMOSPHERE = "atmosphere reached"  # in_atmosphere
    CHUTE_OPENED = "chute opened"  # the descent law asked for the chute (its drag and airspeed limits)
    BRAKING = "braking curve reached"  # the descent law leaves its coast mode
    SETTLED = "fall stopped in the band"  # settled, with a demand above the ground
    LAND = "land demanded"  # demand altitude 0 while hovering, or the hover held ``land_after_hover``


#: ``(phase, event) -> next phase``; any pair not listed is refused.
TRANSITIONS: dict[tuple[Phase, Event], Phase] = {
    (Phase.SLEW, Event.BURN_START): Phase.BURN,
    (Phase.BURN, Event.PERIAPSIS): Phase.COAST,
    (Phase.COAST, Event.ATMOSPHERE): Phase.ENTRY,
    (Phase.ENTRY, Event.CHUTE_OPENED): Phase.PARACHUTE,
    (Phase.ENTRY, Event.BRAKING): Phase.POWERED,
    (Phase.PARACHUTE, Event.BRAKING): Phase.POWERED,
    (Phase.POWERED, Event.SETTLED): Phase.HOVER,
    (Phase.HOVER, Event.LAND): Phase.LANDING,
}


class PhaseError(RuntimeError):
    """An event fired in a phase it does not leave (a defect of the caller, not of the flight)."""


def next_phase(phase: Phase, event: Event) -> Phase:
    """The phase ``event`` leads to from ``phase`` (:data:`TRANSITIONS`); PhaseError if none."""
    try:
        return TRANSITIONS[(phase, event)]
    except KeyError:
        raise PhaseError(f"{event.value!r} does not leave phase {phase.value!r}") from None


# --- the events' conditions ----------------------------------------------------------------------


def burn_due(since_start: float, burn_start: float) -> bool:
    """The planned burn start [s after the mission's first step] is reached."""
    return since_start >= burn_start


def periapsis_reached(periapsis_radius: float, planned_periapsis_altitude: float) -> bool:
    """The osculating periapsis [m from the centre] is down to the plan's altitude [m]: the burn
    ends on the orbit reached, not on a timer."""
    return periapsis_radius <= c.MARS_RADIUS + planned_periapsis_altitude


def in_atmosphere(altitude: float) -> bool:
    """Below the top of the modelled atmosphere (``EXOSPHERE_ALTITUDE``, 200 km)."""
    return altitude < c.EXOSPHERE_ALTITUDE


def settled(error: float, climb: float, band: float, speed: float) -> bool:
    """The fall is stopped at or under the top of the hover band: ``error`` [m] the altitude over
    the demand, ``climb`` [m/s] the climb rate; within the band the climb rate within ``speed`` of
    zero, under it any climb rate from ``-speed`` up (the hover takes the rest out: a drift in the
    wind, or an altitude below the band after braking short on a thinner atmosphere)."""
    return error <= band and (abs(climb) <= speed if error >= -band else climb >= -speed)


@dataclass
class PhaseLog:
    """Each transition: (time [s], from, to, why); a note keeps its phase (from == to)."""

    transitions: list[tuple[float, Phase, Phase, str]]


class PhaseMachine:
    """The current phase and its log; :meth:`fire` moves it on by :data:`TRANSITIONS` only."""

    def __init__(self, phase: Phase = Phase.SLEW) -> None:
        self.phase = phase
        self.log = PhaseLog([])

    def fire(self, t: float, event: Event, why: str) -> Phase:
        """Move on by ``event`` at ``t`` [s]; ``why`` (the measured condition) goes in the log."""
        phase = next_phase(self.phase, event)
        self.log.transitions.append((t, self.phase, phase, why))
        self.phase = phase
        return phase

    def note(self, t: float, why: str) -> None:
        """Log ``why`` at ``t`` without a change of phase (a part's fallback, for the flight's record)."""
        self.log.transitions.append((t, self.phase, self.phase, why))
