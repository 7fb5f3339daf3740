"""Flight phase and the events a simulation reports (touchdown, crash, gimbal lock, fuel out, parachute)."""
from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field


class Phase(enum.Enum):
    """Flight phase: the state is frozen once LANDED or CRASHED."""

    FLYING = "flying"
    LANDED = "landed"  # safe or hard touchdown (the event says which)
    CRASHED = "crashed"


class EventKind(str, enum.Enum):
    LANDED = "landed"
    HARD_LANDING = "hard_landing"  # over the scene's safe touchdown limits, under its crash limits
    CRASHED = "crashed"
    GIMBAL_LOCK = "gimbal_lock"  # a warning: entering |sin theta| < threshold (Euler mode)
    FUEL_EMPTY = "fuel_empty"
    PARACHUTE_DEPLOYED = "parachute_deployed"
    PARACHUTE_LOST = "parachute_lost"


@dataclass(frozen=True)
class Event:
    """Something that happened at sim time ``t`` [s]; ``values`` carries the numbers (SI units)."""

    kind: EventKind
    t: float
    detail: str
    values: Mapping[str, float] = field(default_factory=dict)
