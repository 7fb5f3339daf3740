"""Controller plug-ins: one small interface (state + demand in, throttles out, plus reset).

See :mod:`.base` for the interface and :mod:`.registry` for names and third-party plug-ins.
"""
from __future__ import annotations

from .base import UPRIGHT_EULER, Controller, ControllerError, ControlOutput, Demand, DemandError
from .registry import ENTRY_POINT_GROUP, available_controllers, make_controller

__all__ = [
    "ENTRY_POINT_GROUP",
    "UPRIGHT_EULER",
    "ControlOutput",
    "Controller",
    "ControllerError",
    "Demand",
    "DemandError",
    "available_controllers",
    "make_controller",
]
