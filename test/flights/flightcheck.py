"""Fly a shipped scripted flight, record it, and check the bag with two independent readers."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

from lander_tools.bagio import Bag, read_bag
from lander_tools.launcher import FlightResult
from lander_tools.scripted import load_script

from .spancheck import check_span

REPO = Path(__file__).resolve().parents[2]
#: What the flight tests record: the flight's own topics (not odometry/pose/markers, which the sim
#: only publishes when someone subscribes and which would only slow the test).
FLIGHT_TOPICS = ("/clock", "/lander/state", "/lander/throttle", "/lander/events",
                 "/lander/demand_altitude", "/lander/wind", "/autopilot/status")


def fly_shipped(name: str, tmp_path: Path, storage: str = "mcap") -> tuple[FlightResult, Path]:
    script = load_script(REPO / "flights" / f"{name}.yaml")
    script.topics = FLIGHT_TOPICS
    script.storage = storage
    bag = tmp_path / name
    result = script.run(record=bag)
    assert result.exit_code == 0, f"{name}: {result.outcome}: {result.message}"
    return result, bag


def mcap_counts(bag: Path) -> Counter:
    """Messages per topic decoded by the independent `mcap` + `mcap-ros2-support` reader, from the
    schemas embedded in the file (every message is decoded, not just counted)."""
    from mcap_ros2.reader import read_ros2_messages

    counts: Counter = Counter()
    for m in read_ros2_messages(str(next(bag.glob("*.mcap")))):
        assert m.ros_msg is not None
        counts[m.channel.topic] += 1
    return counts


def check_bag(bag_path: Path, result: FlightResult) -> Bag:
    """Both readers agree with what the recorder wrote; nothing the publishers sent is missing."""
    bag = read_bag(bag_path)
    assert not bag.warnings
    written = {t: n for t, n in result.counts.items() if n}
    assert {t: n for t, n in bag.counts().items() if n} == written
    if bag.storage == "mcap":
        assert dict(mcap_counts(bag_path)) == written
    # The whole flight, exactly (spancheck): state 1 at t = 0 to the end instant, nothing after,
    # the sim's counts, and in lockstep (autopilot, or this launcher piloting) every state answered once.
    counts = mcap_counts(bag_path) if bag.storage == "mcap" else Counter()
    if bag.storage == "mcap":
        with_autopilot = counts.get("/autopilot/status", 0) > 0
        check_span(bag_path, result.sim_time, lockstep=counts.get("/lander/throttle", 0) > 0,
                   sim_only_events=not with_autopilot)
    return bag
