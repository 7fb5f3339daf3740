"""RViz markers: the vehicle's look (:mod:`lander_sim.look`: body, thruster plumes scaled by
throttle, trajectory) as a ``visualization_msgs/MarkerArray``.

RViz's primitives: the body a sphere of diameter ``L``, a plume an arrow (shaft ``0.1 L``, head
``0.2 L`` across; opaque when lit, invisible when off, so its id stays), the trajectory a line
strip ``0.05 L`` wide. Everything is expressed in the world frame (``mars``), transformed with the
core's rotation (:func:`lander_sim.physics.rotation.body_to_world`), so the markers show
correctly even where no TF is broadcast (no tf2_ros).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from lander_ros.stamps import fill_stamp
from lander_sim.look import BODY_COLOUR, PLUME_COLOUR, TRAIL_COLOUR, Colour, Look, Trail
from lander_sim.physics import rotation
from lander_sim.physics.vehicle import Vehicle
from lander_sim.ros.convert import fill_pose
from lander_sim.ros.sim_adapter import Readout

_BODY_ID, _TRAJ_ID, _PLUME_ID0 = 0, 1, 100


class MarkerBuilder:
    """Builds a ``visualization_msgs/MarkerArray`` from core snapshots; keeps the trajectory."""

    def __init__(self, frame_id: str, trajectory_length: int) -> None:
        from geometry_msgs.msg import Point
        from visualization_msgs.msg import Marker

        self._Point, self._Marker = Point, Marker
        self.frame_id = frame_id
        self._trajectory = Trail(trajectory_length)

    def clear_trajectory(self) -> None:
        self._trajectory.clear()

    def record(self, r_W: np.ndarray) -> None:
        """Add one trajectory point (world frame [m])."""
        self._trajectory.add(r_W)

    def build(self, snap: Readout, vehicle: Vehicle) -> Any:
        """MarkerArray for the snapshot ``snap`` of a lander ``vehicle``."""
        from visualization_msgs.msg import MarkerArray

        M = self._Marker
        out = MarkerArray()
        look = Look.of(vehicle)
        size = look.size

        body = self._marker(snap.t, _BODY_ID, "body", M.SPHERE)
        fill_pose(body.pose, snap)
        body.scale.x = body.scale.y = body.scale.z = size
        _paint(body, BODY_COLOUR)
        out.markers.append(body)

        traj = self._marker(snap.t, _TRAJ_ID, "trajectory", M.LINE_STRIP)
        traj.pose.orientation.w = 1.0
        traj.scale.x = 0.05 * size
        _paint(traj, TRAIL_COLOUR)
        traj.points = [self._Point(x=x, y=y, z=z) for x, y, z in self._trajectory]
        out.markers.append(traj)

        for i, plume in enumerate(look.plumes(snap.throttles)):
            arrow = self._marker(snap.t, _PLUME_ID0 + i, "plumes", M.ARROW)
            arrow.pose.orientation.w = 1.0
            start = snap.r_W + rotation.body_to_world(snap.q, np.asarray(plume.start_B, dtype=float))
            end = start + plume.length * rotation.body_to_world(snap.q, np.asarray(plume.direction_B, dtype=float))
            arrow.points = [self._Point(x=float(a), y=float(b), z=float(c)) for a, b, c in (start, end)]
            arrow.scale.x, arrow.scale.y = 0.1 * size, 0.2 * size  # shaft and head diameters [m]
            _paint(arrow, PLUME_COLOUR, 1.0 if plume.throttle > 0.0 else 0.0)
            out.markers.append(arrow)
        return out

    def _marker(self, t: float, mid: int, ns: str, mtype: int) -> Any:
        m = self._Marker()
        m.header.frame_id = self.frame_id
        fill_stamp(m.header.stamp, t)
        m.ns, m.id, m.type, m.action = ns, mid, mtype, self._Marker.ADD
        return m


def _paint(marker: Any, colour: Colour, alpha: float | None = None) -> None:
    """Set ``marker``'s colour (``alpha`` instead of the colour's own opacity, if given)."""
    marker.color.r, marker.color.g, marker.color.b = colour.r, colour.g, colour.b
    marker.color.a = colour.a if alpha is None else alpha
