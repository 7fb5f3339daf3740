"""A bag holds the whole flight, exactly: checked with the independent `mcap` + `mcap-ros2-support`
reader (not our bagio / rosbags), against the simulator's own FLIGHT_ENDED record in the same bag.

What "the whole flight, exactly" means (docs/flying.md, "A flight's span"):

* the first state is state 1 at t = 0 and the last is the end instant the sim announced, with the
  sequence 1, 2, ... N and no gap; nothing stamped after the end on any topic;
* per topic the sim publishes, the bag holds exactly the count the sim reported;
* in lockstep every state was answered exactly once, and every answer is in the bag; where the
  flight has an autopilot (its status in the bag), its status stamped with every state, the end
  state's too (the launcher stops the autopilot only once it has both).
"""
from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lander_ros.flight_span import FlightEnd
from lander_ros.stamps import stamp_to_seconds

FLIGHT_ENDED = 12  # lander_interfaces/msg/FlightEvent.msg
#: Float rounding of a sim time through a ROS stamp (integer ns) [s].
STAMP_EPS = 1e-9


@dataclass
class Span:
    """What the independent reader found in one bag."""

    counts: Counter
    end: FlightEnd
    state_t: list[float]
    state_seq: list[int]
    answers: list[int]
    status_t: list[float]  #: stamps of /autopilot/status (the state each answers, or a report's)
    stamps: dict[str, list[float]] = field(default_factory=dict)
    recorded: set[str] = field(default_factory=set)  #: topics the recorder subscribed to (the bag's channels)


def _t(stamp: Any) -> float:
    return stamp_to_seconds(stamp)


def read_span(bag: Path) -> Span:
    """Read every message of ``bag`` (a folder holding one .mcap) with the independent reader."""
    from mcap_ros2.reader import read_ros2_messages

    files = sorted(Path(bag).glob("*.mcap")) if Path(bag).is_dir() else [Path(bag)]
    assert len(files) == 1, f"{bag}: expected one .mcap file, found {files}"
    from mcap.reader import make_reader

    with open(files[0], "rb") as fh:
        summary = make_reader(fh).get_summary()
    recorded = {c.topic for c in summary.channels.values()} if summary is not None else set()
    counts: Counter = Counter({t: 0 for t in recorded})
    ends, state_t, state_seq, answers, status_t = [], [], [], [], []
    stamps: dict[str, list[float]] = defaultdict(list)
    for m in read_ros2_messages(str(files[0])):
        topic, msg = m.channel.topic, m.ros_msg
        assert msg is not None, f"{topic}: not decoded"
        if topic == "/diagnostics" and not any(st.name.startswith("lander_sim") for st in msg.status):
            # The autopilot's reports (docs/autopilot_node.md): the sim's FLIGHT_ENDED counts its own only.
            counts["/diagnostics (others)"] += 1
        else:
            counts[topic] += 1
        if topic == "/clock":
            stamps[topic].append(_t(msg.clock))
        elif topic == "/diagnostics":
            stamps[topic].append(_t(msg.header.stamp))
        elif hasattr(msg, "header") and topic not in ("/lander/throttle", "/autopilot/status"):
            # Throttles and status are stamped with the state they answer (checked through it).
            stamps[topic].append(_t(msg.header.stamp))
        elif topic == "/lander/markers":
            stamps[topic] += [_t(x.header.stamp) for x in msg.markers]
        if topic == "/lander/state":
            state_t.append(_t(msg.header.stamp))
            state_seq.append(int(msg.sequence))
        elif topic == "/lander/throttle" and msg.state_sequence:
            answers.append(int(msg.state_sequence))
        elif topic == "/autopilot/status":
            status_t.append(_t(msg.header.stamp))
        elif topic == "/lander/events" and msg.kind == FLIGHT_ENDED:
            ends.append(FlightEnd.from_values(list(msg.values)))
    assert len(ends) == 1, f"{bag}: {len(ends)} FLIGHT_ENDED events (expected exactly one)"
    return Span(counts, ends[0], state_t, state_seq, answers, status_t, dict(stamps), recorded)


def check_span(bag: Path, end_t: float | None = None, lockstep: bool = False,
               sim_only_events: bool = True) -> Span:
    """Assert the bag holds the whole flight exactly; ``end_t`` [s]: the end instant expected
    (None: the one the sim announced, e.g. a touchdown). Returns what was read."""
    s = read_span(bag)
    end = s.end
    if end_t is not None:
        assert abs(end.t - end_t) <= STAMP_EPS, f"the flight ended at {end.t!r} s, expected {end_t!r} s"
    assert s.state_seq, "no state in the bag"
    assert s.state_seq == list(range(1, len(s.state_seq) + 1)), (
        f"state sequence has gaps or restarts: first {s.state_seq[:3]}, missing "
        f"{sorted(set(range(1, max(s.state_seq) + 1)) - set(s.state_seq))[:10]}")
    assert s.state_t[0] == 0.0, f"the first state is at t = {s.state_t[0]!r} s, not 0"
    assert abs(s.state_t[-1] - end.t) <= STAMP_EPS, f"the last state is at t = {s.state_t[-1]!r} s, the end at {end.t!r} s"
    for topic, ts in s.stamps.items():
        late = [t for t in ts if t > end.t + STAMP_EPS]
        assert not late, f"{topic}: {len(late)} messages stamped after the end ({end.t!r} s), first at {late[0]!r} s"
    for topic, n in end.counts.items():
        if topic == "/lander/events" and not sim_only_events:
            assert s.counts[topic] >= n, f"{topic}: {s.counts[topic]} in the bag, the sim alone published {n}"
            continue
        if topic in s.recorded:
            assert s.counts[topic] == n, f"{topic}: {s.counts[topic]} in the bag, the sim published {n}"
    if lockstep:
        assert sorted(s.answers) == s.state_seq, (
            f"answers: {len(s.answers)} for {len(s.state_seq)} states; unanswered "
            f"{sorted(set(s.state_seq) - set(s.answers))[:10]}, repeated "
            f"{sorted(k for k, c in Counter(s.answers).items() if c > 1)[:10]}; the sim advanced past "
            f"{end.lockstep_timeouts} states without their answer (FLIGHT_ENDED's lockstep timeouts)")
        if s.status_t:  # the flight has an autopilot
            unreported = sorted(set(s.state_t) - set(s.status_t))
            assert not unreported, (f"/autopilot/status: no status stamped with {len(unreported)} of the "
                                    f"{len(s.state_t)} states, first at {unreported[:3]} s")
    return s
