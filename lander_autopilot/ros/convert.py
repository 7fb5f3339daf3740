"""Messages <-> the controllers' core types, for the autopilot node (no control law here).

* ``lander_interfaces/LanderState`` -> :class:`lander_sim.physics.state.StateView`. The ROS
  ``orientation`` (body -> world, ``(x, y, z, w)``) is the core's world -> body quaternion
  ``(s, x, y, z)`` re-ordered, no conjugate (docs/architecture.md, "Frames and conventions");
  positions and velocities are world frame (``mars``), the angular velocity body frame.
  Time is the state's stamp (sim time) in seconds.
* :class:`lander_autopilot.controllers.ControlOutput` -> ``ThrottleCommand`` answering one state
  (``state_sequence`` and ``header.stamp`` copied from it: lockstep and latency measurement).
* ``AutopilotStatus`` and ``FlightEvent`` filled from the node's bookkeeping; the
  ``DiagnosticArray`` of ``/diagnostics`` from :mod:`.loop_stats`' ``(level, message, values)``.
* ``geometry_msgs/Vector3Stamped`` on ``/lander/demand_velocity`` -> the demand horizontal velocity
  ``(east, north)`` [m/s] in the local ENU frame ``local_enu``
  (:mod:`lander_autopilot.design.translational`).

The test suite converts received messages with these same functions, so the throttles it
expects are bit-for-bit those the node computes.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lander_ros.stamps import stamp_to_seconds
from lander_sim.physics.state import StateView


class StateError(ValueError):
    """A received state cannot be flown on (non-finite field, zero quaternion, wrong thruster count)."""


def state_view(msg, n_thrusters: int | None = None) -> StateView:
    """The core's :class:`StateView` of a ``LanderState`` message.

    Parameters
    ----------
    msg : lander_interfaces.msg.LanderState
    n_thrusters : int, optional
        The vehicle the controller was built for. When given, a state whose ``throttles`` has
        another length (the simulator runs another vehicle) is refused.

    Raises
    ------
    StateError
        Naming the field: a non-finite position, velocity, attitude, rate or fuel, a zero
        quaternion, or the thruster-count mismatch.
    """
    p, v, o, w = msg.position, msg.velocity, msg.orientation, msg.angular_velocity
    r_W = np.array((p.x, p.y, p.z))
    v_W = np.array((v.x, v.y, v.z))
    q = np.array((o.w, o.x, o.y, o.z))  # ROS (x, y, z, w) -> core (s, x, y, z)
    euler = np.array(msg.euler_zxz, dtype=float)
    omega_B = np.array((w.x, w.y, w.z))
    fuel = float(msg.fuel_mass)
    for name, a in (("position", r_W), ("velocity", v_W), ("orientation", q), ("euler_zxz", euler),
                    ("angular_velocity", omega_B)):
        if not np.all(np.isfinite(a)):
            raise StateError(f"state {msg.sequence}: {name} is not finite: {a.tolist()}")
    if not math.isfinite(fuel):
        raise StateError(f"state {msg.sequence}: fuel_mass is not finite: {fuel!r}")
    if not q.any():
        raise StateError(f"state {msg.sequence}: orientation is the zero quaternion (no rotation)")
    if n_thrusters is not None and len(msg.throttles) != n_thrusters:
        raise StateError(
            f"state {msg.sequence} reports {len(msg.throttles)} thrusters but the controller was built for "
            f"{n_thrusters}: the simulator runs another vehicle (set parameter 'scene' to the simulator's scene)"
        )
    return StateView(
        t=stamp_to_seconds(msg.header.stamp), r_W=r_W, v_W=v_W, q=q, euler=euler, omega_B=omega_B, fuel=fuel
    )


def fill_throttle(cmd, state_msg, throttles: Sequence[float]) -> None:
    """Fill a ``ThrottleCommand`` answering ``state_msg``: same stamp, ``state_sequence`` = its sequence."""
    cmd.header.stamp = state_msg.header.stamp
    cmd.state_sequence = state_msg.sequence
    cmd.throttles = [float(x) for x in throttles]


def fill_status(status, *, stamp, controller: str, saturated: bool, steps: int, rejected: int,
                last_error: str, throttles: Sequence[float], state_ok: bool) -> None:
    """Fill an ``AutopilotStatus`` (``stamp``: sim time of the state last answered;
    ``state_ok``: a state arrived within the node's ``state_timeout``)."""
    status.header.stamp = stamp
    status.controller = controller
    status.saturated = bool(saturated)
    status.steps = int(steps)
    status.rejected = int(rejected)
    status.state_ok = bool(state_ok)
    status.last_error = last_error
    status.throttles = [float(x) for x in throttles]


def fill_event(event, *, stamp, kind: int, detail: str, values: Sequence[float] = ()) -> None:
    """Fill a ``FlightEvent``."""
    event.header.stamp = stamp
    event.kind = int(kind)
    event.detail = detail
    event.values = [float(x) for x in values]


def demand_velocity(msg) -> tuple[float, float]:
    """``(east, north)`` [m/s] of a ``Vector3Stamped`` demand velocity, validated.

    Raises :class:`~lander_autopilot.controllers.DemandError` naming what is wrong: a frame other
    than ``local_enu``, a non-zero or non-finite ``z`` (the vertical is the demand altitude's),
    NaN/inf, or an absurd magnitude (above ``MAX_DEMAND_SPEED``).
    """
    from lander_autopilot.controllers.base import Demand, DemandError
    from lander_autopilot.design.translational import LOCAL_FRAME

    frame = msg.header.frame_id
    if frame != LOCAL_FRAME:
        raise DemandError(f"demand velocity in frame {frame!r}: expected header.frame_id {LOCAL_FRAME!r} (east, north, up)")
    v = msg.vector
    if v.z != 0.0:
        raise DemandError(f"demand velocity z = {v.z!r} m/s: must be 0 (the vertical follows the demand altitude)")
    velocity = Demand(velocity=(v.x, v.y)).velocity  # Demand's own checks (finite, magnitude)
    assert velocity is not None
    return velocity


def fill_demand_status(status, demand, mode: str) -> None:
    """The demand in force and the controller's mode into an ``AutopilotStatus``."""
    status.demand_altitude = float(demand.altitude)
    status.velocity_demanded = demand.velocity is not None
    ve, vn = demand.velocity if demand.velocity is not None else (0.0, 0.0)
    status.demand_velocity.x, status.demand_velocity.y, status.demand_velocity.z = float(ve), float(vn), 0.0
    status.mode = mode


def fill_diagnostics(array, *, stamp, hardware_id: str, statuses) -> None:
    """Fill a ``diagnostic_msgs/DiagnosticArray``: one ``DiagnosticStatus`` per
    ``(name, (level, message, values))`` of ``statuses`` (:mod:`lander_autopilot.ros.loop_stats`)."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    array.header.stamp = stamp
    out = []
    for name, (level, message, values) in statuses:
        st = DiagnosticStatus()
        st.level = bytes([level]) if isinstance(st.level, bytes) else level
        st.name, st.message, st.hardware_id = name, message, hardware_id
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        out.append(st)
    array.status = out
