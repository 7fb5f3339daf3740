"""Fly a shipped scripted flight, record it, and check the bag with two independent readers."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from lander_tools.bagio import Bag, read_bag
from lander_tools.launcher import FlightResult
from lander_tools.scripted import load_script

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
    # The sim publishes one /clock with every state, numbering states 1, 2, ... since the
    # last reset: every state is in the bag when the numbers after the reset have no gap.
    s = bag.series("/lander/state")
    seq = s["sequence"].astype(np.int64)
    start = int(np.flatnonzero(seq == 1)[-1])
    np.testing.assert_array_equal(seq[start:], np.arange(1, len(seq) - start + 1))
    # One /clock goes with every state; at t = 0 the sim publishes before and at the reset, when
    # subscriptions may still be matching, so the comparison is over t > 0.
    c = bag.series("/clock")
    assert np.count_nonzero(c["t"] > 0) == np.count_nonzero(s["t"][start:] > 0)
    # Every state up to the end was answered (lockstep), and every answer is in the bag once.
    thr = [m.state_sequence for m in bag.messages("/lander/throttle") if m.state_sequence]
    if thr:
        drops = [i for i in range(1, len(thr)) if thr[i] <= thr[i - 1]]  # the reset restarts at 1
        ans = thr[drops[-1] if drops else 0:]
        end_seq = int(seq[start:][np.searchsorted(s["t"][start:], result.sim_time)])
        # The answer to state 1 (t = 0) races the subscriptions' matching at start-up; from the
        # first recorded answer on, every state up to the end has exactly one answer, in order.
        assert ans[0] <= 2, f"first recorded answer is to state {ans[0]}"
        expected = list(range(ans[0], end_seq))
        assert ans[: len(expected)] == expected, (
            f"answers missing or out of order: {sorted(set(expected) - set(ans))[:10]}"
        )
    return bag
