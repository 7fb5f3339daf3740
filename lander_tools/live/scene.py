"""The live 3-D scene: the vehicle's look (:mod:`lander_sim.look`) at one lander state, as
foxglove messages (``/live/tf`` and ``/live/scene`` of :mod:`lander_tools.live.bridge`).

Frames (:mod:`lander_tools.live.views`): the body, its plumes and the parachute are drawn in
``base_link`` (``frame_locked``: they move with the lander's transform), the trail and the
ground in ``surface``. Foxglove's primitives: the body a box ``L x L x 0.6 L``, a plume a cone
(cylinder narrowing to 0.3) ``0.15 L`` across, only when lit; the trail a line 2 px wide on
screen; the parachute an ellipsoid; the ground a 400 m square 0.1 m thick below the lander.

foxglove is imported in the functions that use it (the bridge's own rule: importing the bridge,
for its argv or topics, does not load it).
"""
from __future__ import annotations

from typing import Any

from lander_sim import look
from lander_tools.live import views

#: Side [m] of the ground square under the lander, and its thickness [m].
GROUND_SIDE, GROUND_THICKNESS = 400.0, 0.1
GROUND_COLOUR = look.Colour(0.6, 0.3, 0.2, 1.0)


def messages(tracker: views.SceneTracker, msg: Any, here: tuple[float, float, float]) -> tuple[Any, Any]:
    """``(FrameTransforms, SceneUpdate)`` of the ``LanderState`` ``msg``, whose position the
    ``tracker`` has just added (``here``: that position in the ``surface`` frame [m])."""
    from foxglove.messages import (
        CubePrimitive,
        CylinderPrimitive,
        FrameTransform,
        FrameTransforms,
        LinePrimitive,
        Point3,
        SceneEntity,
        SceneUpdate,
        SpherePrimitive,
        Timestamp,
        Vector3,
    )

    stamp = Timestamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
    p, q = msg.position, msg.orientation
    transforms = FrameTransforms(transforms=[
        _transform(FrameTransform, Vector3, stamp, "mars", "surface", tracker.surface_pose()),
        _transform(FrameTransform, Vector3, stamp, "mars", "base_link",
                   views.Pose((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))),
    ])
    shape = tracker.look
    size = shape.size
    grey, orange, blue = _colour(look.BODY_COLOUR), _colour(look.PLUME_COLOUR), _colour(look.TRAIL_COLOUR)
    body = SceneEntity(timestamp=stamp, frame_id="base_link", id="body", frame_locked=True,
                       cubes=[CubePrimitive(pose=_pose(views.Pose((0, 0, 0), (0, 0, 0, 1))),
                                            size=Vector3(x=size, y=size, z=0.6 * size), color=grey)])
    plumes = []
    for plume in shape.plumes(msg.throttles):
        pose, length = views.plume_pose(plume)
        if length > 0:
            plumes.append(CylinderPrimitive(pose=_pose(pose), size=Vector3(x=0.15 * size, y=0.15 * size, z=length),
                                            bottom_scale=1.0, top_scale=0.3, color=orange))
    thrust = SceneEntity(timestamp=stamp, frame_id="base_link", id="plumes", frame_locked=True, cylinders=plumes)
    trail = SceneEntity(timestamp=stamp, frame_id="surface", id="trail", lines=[LinePrimitive(
        pose=_pose(views.Pose((0, 0, 0), (0, 0, 0, 1))), thickness=2.0, scale_invariant=True, color=blue,
        points=[Point3(x=a, y=b, z=c) for a, b, c in tracker.trail_S])])
    ground = SceneEntity(timestamp=stamp, frame_id="surface", id="ground", cubes=[CubePrimitive(
        pose=_pose(views.Pose((here[0], here[1], -GROUND_THICKNESS / 2), (0, 0, 0, 1))),
        size=Vector3(x=GROUND_SIDE, y=GROUND_SIDE, z=GROUND_THICKNESS), color=_colour(GROUND_COLOUR))])
    entities = [body, thrust, trail, ground]
    if msg.parachute_deployed:
        (cx, cy, cz), (ex, ey, ez) = shape.parachute_centre_B(), shape.parachute_extent()
        entities.append(SceneEntity(timestamp=stamp, frame_id="base_link", id="parachute", frame_locked=True,
                                    spheres=[SpherePrimitive(pose=_pose(views.Pose((cx, cy, cz), (0, 0, 0, 1))),
                                                             size=Vector3(x=ex, y=ey, z=ez),
                                                             color=_colour(look.PARACHUTE_COLOUR))]))
    return transforms, SceneUpdate(entities=entities)


def _colour(c: look.Colour) -> Any:
    from foxglove.messages import Color

    return Color(r=c.r, g=c.g, b=c.b, a=c.a)


def _pose(p: views.Pose) -> Any:
    from foxglove.messages import Pose, Quaternion, Vector3

    return Pose(position=Vector3(x=p.position[0], y=p.position[1], z=p.position[2]),
                orientation=Quaternion(x=p.orientation[0], y=p.orientation[1], z=p.orientation[2], w=p.orientation[3]))


def _transform(FrameTransform: Any, Vector3: Any, stamp: Any, parent: str, child: str, p: views.Pose) -> Any:
    from foxglove.messages import Quaternion

    return FrameTransform(timestamp=stamp, parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=p.position[0], y=p.position[1], z=p.position[2]),
                          rotation=Quaternion(x=p.orientation[0], y=p.orientation[1], z=p.orientation[2],
                                              w=p.orientation[3]))
