"""A recorded flight as the student page's state records: what ``lander view BAG`` serves.

Each ``/lander/state`` of the bag becomes the record the live bridge would have sent for it
(:func:`lander_tools.live.views.state_record` and :func:`~lander_tools.live.views.view_fields`,
the same surface frame and look), with the demand altitude and controller of the last
``/autopilot/status`` at or before its stamp and the mean wind in force: the simulator's
``mean_wind_W`` in its last ``/diagnostics`` report, or in a bag without those reports the last
finite ``/lander/wind`` (the scene's before any). The vehicle's look comes from the scene named in the bag's metadata;
a bag without one (an MCAP cut short) is drawn with :data:`DEFAULT_LOOK_SCENE`'s.

Plain Python (rosbags, no rclpy): see :mod:`lander_tools.bagio`.
"""
from __future__ import annotations

import bisect
import math
import os
from dataclasses import dataclass
from typing import Any

from lander_ros.flight_span import sim_report
from lander_ros.stamps import stamp_to_seconds
from lander_tools.live import views

#: The scene whose vehicle draws a bag that names no scene.
DEFAULT_LOOK_SCENE = "hover"


@dataclass
class Replay:
    """A bag's flight for the page: its records (sim time order), scene and a note on what was assumed."""

    records: list[dict[str, Any]]
    scene: str
    note: str = ""

    def page_json(self) -> dict[str, Any]:
        return {"scene": self.scene, "note": self.note, "records": self.records}


def _latest_before(times: list[float], values: list[Any], t: float, default: Any) -> Any:
    i = bisect.bisect_right(times, t + 1e-9) - 1
    return values[i] if i >= 0 else default


def load(path: str | os.PathLike[str]) -> Replay:
    """The replay of the bag at ``path``. ``BagError`` (a ``ValueError``) for an unreadable bag or
    one without a ``/lander/state``; ``ValueError`` for a scene that cannot be loaded."""
    from lander_sim.look import Look
    from lander_sim.scenes import load_scene
    from lander_tools.bagio import BagError, read_bag

    bag = read_bag(path, ["/lander/state", "/autopilot/status", "/lander/wind", "/diagnostics"])
    if "/lander/state" not in bag:
        raise BagError(f"{path}: no /lander/state in this bag: nothing to replay")
    name, note = bag.meta.get("scene", ""), ""
    if not name:
        name, note = DEFAULT_LOOK_SCENE, f"the bag names no scene: drawn with the '{DEFAULT_LOOK_SCENE}' vehicle"
    scene = load_scene(name)
    tracker = views.SceneTracker(Look.of(scene.vehicle), trail_length=1, fixed_pivot=not scene.translation)
    status_t: list[float] = []
    status: list[tuple[float | None, str]] = []
    if "/autopilot/status" in bag:
        for m in bag.topics["/autopilot/status"].messages:
            status_t.append(stamp_to_seconds(m.header.stamp))
            status.append((float(m.demand_altitude), str(m.controller)))
    wind_t: list[float] = []
    winds: list[list[float]] = []
    for m in bag.topics["/diagnostics"].messages if "/diagnostics" in bag else []:
        w = views.parse_wind((sim_report(m) or {}).get("mean_wind_W"))
        if w is not None:
            wind_t.append(stamp_to_seconds(m.header.stamp))
            winds.append(w)
    if not winds and "/lander/wind" in bag:
        for m in bag.topics["/lander/wind"].messages:
            w = [float(m.vector.x), float(m.vector.y), float(m.vector.z)]
            if all(math.isfinite(v) for v in w):  # the simulator refuses the others
                wind_t.append(stamp_to_seconds(m.header.stamp))
                winds.append(w)
    scene_wind = [float(v) for v in scene.wind_W]
    records = []
    last_seq = None
    for msg in bag.topics["/lander/state"].messages:
        if last_seq is not None and msg.sequence < last_seq:
            tracker.reset()  # a reset in the recorded flight: a new epoch
        last_seq = msg.sequence
        t = stamp_to_seconds(msg.header.stamp)
        demand, controller = _latest_before(status_t, status, t, (None, bag.meta.get("controller", "")))
        rec = views.state_record(msg, demand, controller, False)
        p, q = msg.position, msg.orientation
        here = tracker.add((p.x, p.y, p.z))
        rec["position_S"], rec["up_S"] = list(here), list(tracker.body_up((q.x, q.y, q.z, q.w)))
        rec.update(views.view_fields(tracker, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), msg.throttles,
                                     bool(msg.parachute_deployed)))
        rec["wind_W"] = _latest_before(wind_t, winds, t, scene_wind)
        rec["controller_params"] = ""
        records.append(rec)
    return Replay(records, name, note)
