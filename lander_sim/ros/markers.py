"""RViz markers: lander body, thruster plumes scaled by throttle, trajectory.

Everything is expressed in the world frame (``mars``), transformed with the
core's rotation (:func:`lander_sim.physics.rotation.body_to_world`), so the
markers show correctly even where no TF is broadcast (no tf2_ros).
"""
from __future__ import annotations

from collections import deque

import numpy as np

from lander_sim.physics import rotation
from lander_sim.ros.convert import fill_pose, fill_stamp

#: Plume length at full throttle, in lander sizes.
PLUME_LENGTH_PER_SIZE = 2.0

_BODY_ID, _TRAJ_ID, _PLUME_ID0 = 0, 1, 100


class MarkerBuilder:
    """Builds a ``visualization_msgs/MarkerArray`` from core snapshots; keeps the trajectory."""

    def __init__(self, frame_id: str, trajectory_length: int) -> None:
        from geometry_msgs.msg import Point
        from visualization_msgs.msg import Marker

        self._Point, self._Marker = Point, Marker
        self.frame_id = frame_id
        self._trajectory: deque = deque(maxlen=trajectory_length)

    def clear_trajectory(self) -> None:
        self._trajectory.clear()

    def record(self, r_W: np.ndarray) -> None:
        """Add one trajectory point (world frame [m])."""
        self._trajectory.append((float(r_W[0]), float(r_W[1]), float(r_W[2])))

    def build(self, snap, vehicle):
        """MarkerArray for the snapshot ``snap`` of a lander ``vehicle`` (:class:`lander_sim.physics.vehicle.Vehicle`)."""
        from visualization_msgs.msg import MarkerArray

        M = self._Marker
        out = MarkerArray()
        size = float(vehicle.size)

        body = self._marker(snap.t, _BODY_ID, "body", M.SPHERE)
        fill_pose(body.pose, snap)
        body.scale.x = body.scale.y = body.scale.z = size
        body.color.r, body.color.g, body.color.b, body.color.a = 0.8, 0.8, 0.8, 1.0
        out.markers.append(body)

        traj = self._marker(snap.t, _TRAJ_ID, "trajectory", M.LINE_STRIP)
        traj.pose.orientation.w = 1.0
        traj.scale.x = 0.05 * size
        traj.color.r, traj.color.g, traj.color.b, traj.color.a = 0.2, 0.6, 1.0, 1.0
        traj.points = [self._Point(x=x, y=y, z=z) for x, y, z in self._trajectory]
        out.markers.append(traj)

        for i, (thr, throttle) in enumerate(zip(vehicle.thrusters, snap.throttles)):
            plume = self._marker(snap.t, _PLUME_ID0 + i, "plumes", M.ARROW)
            plume.pose.orientation.w = 1.0
            # Exhaust leaves along +d_i from the point of action p_i (body frame), force is along -d_i.
            start = snap.r_W + rotation.body_to_world(snap.q, np.asarray(thr.position_B, dtype=float))
            length = PLUME_LENGTH_PER_SIZE * size * float(throttle)
            end = start + length * rotation.body_to_world(snap.q, np.asarray(thr.direction_B, dtype=float))
            plume.points = [self._Point(x=float(a), y=float(b), z=float(c)) for a, b, c in (start, end)]
            plume.scale.x, plume.scale.y = 0.1 * size, 0.2 * size  # shaft and head diameters [m]
            plume.color.r, plume.color.g, plume.color.b = 1.0, 0.5, 0.1
            plume.color.a = 1.0 if throttle > 0.0 else 0.0  # invisible when off, id kept stable
            out.markers.append(plume)
        return out

    def _marker(self, t: float, mid: int, ns: str, mtype: int):
        m = self._Marker()
        m.header.frame_id = self.frame_id
        fill_stamp(m.header.stamp, t)
        m.ns, m.id, m.type, m.action = ns, mid, mtype, self._Marker.ADD
        return m
