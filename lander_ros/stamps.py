"""Sim time in ``builtin_interfaces/Time`` stamps: one conversion each way for every node and tool.

A stamp holds integer nanoseconds (``sec``, ``nanosec``); sim time is a float of seconds. Writing
rounds to the nearest nanosecond; reading divides exactly (``sec + nanosec / 1e9``), so reading
what was written gives the float nearest to the nanosecond the stamp holds.
"""
from __future__ import annotations

from typing import Any

_NS = 1_000_000_000


def sim_time_to_ns(t: float) -> int:
    """Sim time [s] as integer nanoseconds, rounded to nearest (ROS time resolution)."""
    return int(round(t * 1e9))


def fill_stamp(stamp: Any, t: float) -> None:
    """Write sim time ``t`` [s] into a ``builtin_interfaces/Time``."""
    stamp.sec, stamp.nanosec = divmod(sim_time_to_ns(t), _NS)


def stamp_to_seconds(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` (a message's ``header.stamp``, ``/clock``'s ``clock``) as seconds."""
    return stamp.sec + stamp.nanosec / _NS
