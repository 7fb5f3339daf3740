"""What the live channels show, computed from a lander state: plain numpy, no rclpy, no foxglove.

The bridge (:mod:`lander_tools.live.bridge`) sends these; :mod:`lander_tools.live.scene` turns the
3-D scene into foxglove messages. Frames
(docs/architecture.md, "Frames and conventions"):

* ``mars``: planet-centred world frame of the simulator (positions ~3.4e6 m from its origin).
* ``surface``: a local frame fixed to the planet, origin on the surface (radius ``MARS_RADIUS``)
  straight below the first position seen, z up (radial), so the 3-D view works with small
  numbers (a float32 renderer at 3.4e6 m would quantise to ~0.25 m).
* ``base_link``: the body frame; the core's ``q = (s, x, y, z)`` maps world to body
  (dynamics reference, eq 12-13), which read actively is the orientation of
  ``base_link`` in ``mars`` (the conversion is :func:`lander_sim.ros.convert.ros_orientation`).

What the scene shows of the vehicle (body, plumes scaled by throttle, parachute, trail) is its
look, :mod:`lander_sim.look`, the one the sim node's RViz markers draw too.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lander_ros.stamps import stamp_to_seconds
from lander_sim.look import Look, Plume, Trail
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.rotation import body_to_world, matrix_to_quat, quat_to_matrix

#: Phase names of ``LanderState.phase`` (lander_interfaces/msg/LanderState.msg).
PHASES = ("flying", "landed", "crashed")
#: Event kind names of ``FlightEvent.kind`` (lander_interfaces/msg/FlightEvent.msg), by value.
EVENT_KINDS = ("LANDED", "CRASHED", "GIMBAL_LOCK", "FUEL_OUT", "PARACHUTE_DEPLOYED", "PARACHUTE_DESTROYED",
               "INPUT_REJECTED", "CONTROLLER_SWITCHED", "COMMAND_STALE", "HARD_LANDING",
               "LANDING_UNREACHABLE", "MODE_CHANGED", "FLIGHT_ENDED")


def event_name(kind: int) -> str:
    """``FlightEvent.kind`` as its constant's name (``KIND_<n>`` for a value this version lacks)."""
    return EVENT_KINDS[kind] if 0 <= kind < len(EVENT_KINDS) else f"KIND_{kind}"


def state_record(msg: Any, demand_altitude: float | None, controller: str, paused: bool) -> dict[str, Any]:
    """The ``/live/state`` JSON record of one ``LanderState`` (SI units; frames in the names).

    ``t`` is the state's sim time [s]; ``euler_zxz`` (phi, theta, psi) [rad] per
    dynamics reference eq 3; ``omega_B`` body rates [rad/s]; ``velocity_W`` [m/s].
    """
    st = msg.header.stamp
    v, w = msg.velocity, msg.angular_velocity
    return {
        "t": stamp_to_seconds(st),
        "sequence": int(msg.sequence),
        "altitude": msg.altitude,
        "climb_rate": msg.climb_rate,
        "ground_speed": msg.ground_speed,
        "euler_zxz": [float(a) for a in msg.euler_zxz],
        "omega_B": [w.x, w.y, w.z],
        "velocity_W": [v.x, v.y, v.z],
        "throttles": [float(x) for x in msg.throttles],
        "fuel": msg.fuel_mass,
        "mass": msg.mass,
        "phase": PHASES[msg.phase] if msg.phase < len(PHASES) else str(msg.phase),
        "parachute": bool(msg.parachute_deployed),
        "stabiliser": bool(msg.stabiliser_on),
        "demand_altitude": demand_altitude,
        "controller": controller,
        "paused": paused,
    }


def parse_wind(text: str | None) -> list[float] | None:
    """The simulator's ``mean_wind_W`` diagnostics value (``"x y z"`` [m/s], world frame) as a list;
    None when absent or not three finite numbers."""
    try:
        wind = [float(v) for v in (text or "").split()]
    except ValueError:
        return None
    return wind if len(wind) == 3 and all(math.isfinite(v) for v in wind) else None


#: JSON schema of ``/live/state`` (what Foxglove's plot panel offers as fields).
STATE_SCHEMA: dict[str, Any] = {
    "type": "object",
    "title": "lander.LiveState",
    "properties": {
        "t": {"type": "number", "description": "sim time [s]"},
        "sequence": {"type": "integer"},
        "altitude": {"type": "number", "description": "[m] above the surface"},
        "climb_rate": {"type": "number", "description": "[m/s]"},
        "ground_speed": {"type": "number", "description": "[m/s]"},
        "euler_zxz": {"type": "array", "items": {"type": "number"}, "description": "ZXZ Euler angles [rad]"},
        "omega_B": {"type": "array", "items": {"type": "number"}, "description": "body rates [rad/s], body frame"},
        "velocity_W": {"type": "array", "items": {"type": "number"}, "description": "[m/s], world frame"},
        "throttles": {"type": "array", "items": {"type": "number"}, "description": "per thruster, 0..1"},
        "fuel": {"type": "number", "description": "[kg]"},
        "mass": {"type": "number", "description": "[kg]"},
        "phase": {"type": "string"},
        "parachute": {"type": "boolean"},
        "stabiliser": {"type": "boolean"},
        "demand_altitude": {"type": ["number", "null"], "description": "[m]"},
        "controller": {"type": "string"},
        "paused": {"type": "boolean"},
        "position_S": {"type": "array", "items": {"type": "number"}, "description": "[m], surface frame"},
        "up_S": {"type": "array", "items": {"type": "number"}, "description": "body z axis, surface frame"},
        "position_W": {"type": "array", "items": {"type": "number"}, "description": "[m], world frame"},
        "q_SB": {"type": "array", "items": {"type": "number"},
                 "description": "orientation of base_link in surface (x, y, z, w)"},
        "tilt": {"type": "number", "description": "[rad] between the body z axis and the local vertical"},
        "size": {"type": "number", "description": "lander size L [m]"},
        "plumes_B": {"type": "array", "items": {"type": "array", "items": {"type": "number"}},
                     "description": "lit plumes: start and end [m], body frame"},
        "parachute_B": {"type": ["array", "null"], "items": {"type": "number"},
                        "description": "open canopy: centre and extent [m], body frame"},
        "fixed_pivot": {"type": "boolean", "description": "the body turns about a fixed pivot"},
        "q_WB": {"type": "array", "items": {"type": "number"},
                 "description": "orientation of base_link in mars (x, y, z, w)"},
        "wind_W": {"type": ["array", "null"], "items": {"type": "number"},
                   "description": "mean wind in force [m/s], world frame"},
        "controller_params": {"type": "string", "description": "the controller's parameters in force (YAML)"},
    },
}


@dataclass(frozen=True)
class Pose:
    """A pose: ``position`` [m] and ``orientation`` (x, y, z, w) of a child frame in its parent."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]


@dataclass
class SceneTracker:
    """The 3-D scene of a flight: the local ``surface`` frame and the trail in it, for a vehicle
    of ``look`` (:class:`lander_sim.look.Look`: its size and thrusters)."""

    look: Look
    trail_length: int = 2000
    fixed_pivot: bool = False
    origin_W: np.ndarray | None = None
    R_WS: np.ndarray | None = None  # columns: the surface frame's axes in world coordinates
    trail_S: Trail = field(init=False)

    def __post_init__(self) -> None:
        self.trail_S = Trail(self.trail_length)

    def reset(self) -> None:
        """New epoch (reset / scene load): forget the trail and re-anchor the surface frame."""
        self.origin_W = self.R_WS = None
        self.trail_S.clear()

    def _anchor(self, r_W: np.ndarray) -> None:
        up = r_W / np.linalg.norm(r_W)
        # East-like x: any axis not parallel to up, made orthogonal (the world z unless near a pole).
        ref = np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        x = np.cross(ref, up)
        x /= np.linalg.norm(x)
        y = np.cross(up, x)
        self.R_WS = np.column_stack([x, y, up])
        self.origin_W = MARS_RADIUS * up

    def surface_pose(self) -> Pose:
        """The ``surface`` frame in ``mars``."""
        assert self.origin_W is not None and self.R_WS is not None
        # The core's R(q) maps world to the child frame (dynamics reference eq 12-13): R = R_WS^T;
        # the same q read actively is the ROS orientation of ``surface`` in ``mars``.
        q = matrix_to_quat(self.R_WS.T)
        o = self.origin_W
        return Pose((float(o[0]), float(o[1]), float(o[2])), (float(q[1]), float(q[2]), float(q[3]), float(q[0])))

    def add(self, r_W: Sequence[float]) -> tuple[float, float, float]:
        """Record a world position [m]; returns it in the ``surface`` frame [m]."""
        r = np.asarray(r_W, dtype=float)
        if self.origin_W is None:
            self._anchor(r)
        assert self.R_WS is not None and self.origin_W is not None
        p = self.R_WS.T @ (r - self.origin_W)
        point = (float(p[0]), float(p[1]), float(p[2]))
        self.trail_S.add(point)
        return point

    def body_up(self, q_xyzw: Sequence[float]) -> tuple[float, float, float]:
        """The body z axis (the lander's "up") in the ``surface`` frame, from the ROS orientation
        ``(x, y, z, w)`` of ``base_link`` in ``mars``."""
        assert self.R_WS is not None
        x, y, z, w = q_xyzw
        z_W = body_to_world(np.array([w, x, y, z], dtype=float), np.array([0.0, 0.0, 1.0]))
        u = self.R_WS.T @ z_W
        return (float(u[0]), float(u[1]), float(u[2]))


def plume_pose(plume: Plume) -> tuple[Pose, float]:
    """Pose (in ``base_link``) and length [m] of a cylinder along the plume: Foxglove's cylinder
    primitive has its axis along its local z, centred on its pose."""
    a, b = np.asarray(plume.start_B), np.asarray(plume.end_B)
    d = b - a
    length = float(np.linalg.norm(d))
    m = (a + b) / 2.0
    centre = (float(m[0]), float(m[1]), float(m[2]))
    if length < 1e-12:
        return Pose(centre, (0.0, 0.0, 0.0, 1.0)), 0.0
    z = d / length
    axis = np.cross([0.0, 0.0, 1.0], z)
    s = float(np.linalg.norm(axis))
    c = float(z[2])
    if s < 1e-12:  # parallel or anti-parallel to z
        return Pose(centre, (0.0, 0.0, 0.0, 1.0) if c > 0 else (1.0, 0.0, 0.0, 0.0)), length
    axis /= s
    half = math.atan2(s, c) / 2.0
    sh = math.sin(half)
    return Pose(centre, (float(axis[0]) * sh, float(axis[1]) * sh, float(axis[2]) * sh, math.cos(half))), length


def view_fields(tracker: SceneTracker, r_W: Sequence[float], q_xyzw: Sequence[float], throttles: Sequence[float],
                parachute: bool) -> dict[str, Any]:
    """What the student page's 3-D view draws of one state, besides ``position_S`` and ``up_S``:
    the body's orientation in the ``surface`` frame, the lit plumes and the open canopy in the
    body frame (the vehicle's look, :mod:`lander_sim.look`), the tilt and the world position.

    With ``R_WB = R(q)^T`` (dynamics reference eq 12-13: ``R(q)`` maps world to body) and the
    surface axes ``R_WS``, the body in the surface frame is ``R_SB = R_WS^T R_WB``; its
    quaternion is given in the ROS/three.js order ``(x, y, z, w)``, read actively. The tilt is
    ``acos(z_B . r_W / |r_W|)``: the angle between the body z axis and the local vertical.
    ``tracker`` must have been given a position (:meth:`SceneTracker.add`).
    """
    assert tracker.R_WS is not None
    x, y, z, w = q_xyzw
    R_WB = quat_to_matrix(np.array([w, x, y, z], dtype=float)).T
    R_SB = tracker.R_WS.T @ R_WB
    q = matrix_to_quat(R_SB.T)  # the core's q of a rotation maps its parent to its child: R(q) = R_SB^T
    r = np.asarray(r_W, dtype=float)
    tilt = math.acos(float(np.clip(R_WB[:, 2] @ r / np.linalg.norm(r), -1.0, 1.0)))
    shape = tracker.look
    plumes = [[*p.start_B, *p.end_B] for p in shape.plumes(throttles) if p.length > 0]
    canopy = [*shape.parachute_centre_B(), *shape.parachute_extent()] if parachute else None
    return {"q_SB": [float(q[1]), float(q[2]), float(q[3]), float(q[0])], "tilt": tilt, "size": shape.size,
            "plumes_B": plumes, "parachute_B": canopy, "fixed_pivot": tracker.fixed_pivot,
            "position_W": [float(v) for v in r], "q_WB": [float(v) for v in q_xyzw]}


#: The graphs' fields of a state record (what :class:`History` keeps of each).
HISTORY_FIELDS = ("t", "altitude", "climb_rate", "euler_zxz", "throttles", "demand_altitude", "fuel",
                  "ground_speed", "tilt")


@dataclass
class History:
    """The graph fields of the states of one epoch, from t = 0, in at most ``capacity`` records.

    Records are kept one per bin of ``spacing`` seconds of sim time (the first state in each);
    when full, the spacing doubles and the records are binned again, so the whole flight stays
    drawn at one resolution whatever its length (a page that opens late draws the flight from
    its start): consecutive records are ``spacing`` apart to within one state interval.
    """

    capacity: int = 4000
    records: list[dict[str, Any]] = field(default_factory=list)
    spacing: float = 0.0  # [s] bin width; 0: every state kept

    def _bin(self, t: float) -> float:
        return math.floor(t / self.spacing + 1e-9) if self.spacing > 0 else t

    def add(self, record: dict[str, Any]) -> None:
        if self.records and record["t"] < self.records[-1]["t"]:
            self.clear()  # a new epoch (reset)
        if self.records and self._bin(record["t"]) == self._bin(self.records[-1]["t"]):
            return
        self.records.append({k: record.get(k) for k in HISTORY_FIELDS})
        while len(self.records) > self.capacity:
            span = self.records[-1]["t"] - self.records[0]["t"]
            self.spacing = 2.0 * self.spacing if self.spacing > 0 else 2.0 * span / (len(self.records) - 1)
            kept = [self.records[0]]
            for r in self.records[1:]:
                if self._bin(r["t"]) != self._bin(kept[-1]["t"]):
                    kept.append(r)
            self.records = kept

    def clear(self) -> None:
        self.records, self.spacing = [], 0.0
