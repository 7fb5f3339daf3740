"""A flight's span as the simulator keeps it: who listens before it starts, what it published when it ends.

Plain Python (no rclpy), shared by the sim node (which answers ``/lander/subscribers`` and builds
the ``FlightEvent.FLIGHT_ENDED``) and whoever starts a flight or checks a recording against it
(``lander fly``, the tests). docs/sim_node.md, "A flight's span".

Before a flight starts, ``/lander/subscribers`` (``std_srvs/Trigger``) answers with the number of
subscriptions each of the simulator's outputs has *matched* (its writers, not just the graph), as
``"/clock=2 /lander/state=3 ..."`` (:func:`format_matched`, :func:`parse_matched`): a launcher
resets only when everyone it waits for is matched, so state 1 at t = 0 reaches them all.

The simulator stops by itself at the flight's end instant (its ``end_time`` parameter, or a
touchdown listed in ``end_on``): it publishes the state of that instant, one last
``/diagnostics`` and then the ``FLIGHT_ENDED`` event, and advances no further until a reset or
a new scene. The event's ``values`` are::

    [t_end, reason, n(/clock), n(/lander/state), n(/lander/odom), n(/lander/pose),
     n(/lander/markers), n(/lander/events), n(/diagnostics), lockstep_timeouts,
     n(/lander/sensors/imu), ..., n(/lander/sensors/ground_fix)]

``t_end`` [s] the end instant, ``reason`` an index into :data:`END_REASONS`, ``n(topic)`` the
messages the simulator published on that topic since the flight's reset (``/lander/events``
includes this event), and ``lockstep_timeouts`` the states of this flight the simulator advanced
past without the controller's answer (its ``lockstep_timeout``): in lockstep the autopilot answers
every state once, except these, so a recording's ``/lander/throttle`` holds ``n(/lander/state) -
lockstep_timeouts`` answers or more (an answer may come after its timeout), and a flight with any
is not the deterministic one. Events recorded before it was added have no such value (read as 0).
The counts of the sensor topics (:data:`SENSOR_TOPICS`, in that order) follow only when the
flight's scene has sensors (a ``sensors:`` section): a flight without them carries the values above
and nothing more. Its ``detail`` says the same in words.

Every flight has a number (0 the node's first, one more at each reset or scene load), in the
simulator's ``/diagnostics`` (key ``flight``) and in its pause answer (``..., flight N``,
:func:`paused_flight`): ``/diagnostics`` is published while paused too (wall-paced), and a
recorder released just before a reset tells the old flight's last report by its number.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

#: Why a flight ended; ``FLIGHT_ENDED.values[1]`` indexes this tuple.
END_REASONS: tuple[str, ...] = ("time-limit", "landed", "crashed")
#: The simulator's outputs, in the order of their counts in ``FLIGHT_ENDED.values[2:]``.
COUNTED_TOPICS: tuple[str, ...] = (
    "/clock",
    "/lander/state",
    "/lander/odom",
    "/lander/pose",
    "/lander/markers",
    "/lander/events",
    "/diagnostics",
)
#: The simulator's sensor outputs (docs/sim_node.md), published only for a scene with sensors, in
#: the order of their counts after ``lockstep_timeouts`` in ``FLIGHT_ENDED.values``.
#: A sensor's topic is ``/lander/sensors/<key>``, its key in the scene's ``sensors:`` section.
SENSOR_KEYS: tuple[str, ...] = ("imu", "star_tracker", "altimeter", "doppler", "ground_fix")
SENSOR_TOPICS: tuple[str, ...] = tuple(f"/lander/sensors/{key}" for key in SENSOR_KEYS)
#: The simulator's inputs (its subscriptions): per-thruster throttles and the wind (world frame).
SIM_INPUT_TOPICS: tuple[str, ...] = ("/lander/throttle", "/lander/wind")
#: Phases a touchdown may end the flight on (the ``end_on`` parameter).
END_ON_CHOICES: tuple[str, ...] = ("landed", "crashed")


@dataclass
class FlightEnd:
    """A decoded ``FLIGHT_ENDED``: end instant [s], reason, messages published per topic and the
    states advanced past without the controller's answer (``lockstep_timeouts``). ``counts`` holds
    the sensor topics only for a flight with sensors (all of :data:`SENSOR_TOPICS` then)."""

    t: float
    reason: str
    counts: dict[str, int] = field(default_factory=dict)
    lockstep_timeouts: int = 0

    @property
    def has_sensors(self) -> bool:
        """Whether the counts hold the sensor topics (a flight of a scene with sensors)."""
        return any(t in self.counts for t in SENSOR_TOPICS)

    def topics(self) -> tuple[str, ...]:
        """The topics the values count, in their order."""
        return COUNTED_TOPICS + (SENSOR_TOPICS if self.has_sensors else ())

    def values(self) -> list[float]:
        """The event's ``values`` array (see the module docstring)."""
        sensors = [float(self.counts.get(t, 0)) for t in SENSOR_TOPICS] if self.has_sensors else []
        return [float(self.t), float(END_REASONS.index(self.reason))] + [
            float(self.counts.get(topic, 0)) for topic in COUNTED_TOPICS
        ] + [float(self.lockstep_timeouts)] + sensors

    def detail(self) -> str:
        """One line a person reads: when, why and what was published."""
        counts = ", ".join(f"{t} {self.counts.get(t, 0)}" for t in self.topics())
        missed = f"; {self.lockstep_timeouts} lockstep timeouts" if self.lockstep_timeouts else ""
        return f"flight ended at t = {self.t!r} s ({self.reason}); published since the reset: {counts}{missed}"

    @classmethod
    def from_values(cls, values: list[float]) -> FlightEnd:
        """Decode an event's ``values``; ValueError naming what is wrong with them."""
        n = 2 + len(COUNTED_TOPICS)
        if len(values) not in (n, n + 1, n + 1 + len(SENSOR_TOPICS)):
            raise ValueError(f"FLIGHT_ENDED carries {len(values)} values, expected {n + 1} "
                             f"(t_end, reason, counts, lockstep_timeouts) or {n + 1 + len(SENSOR_TOPICS)} "
                             "(and the sensors' counts)")
        code = int(values[1])
        if not 0 <= code < len(END_REASONS) or code != values[1]:
            raise ValueError(f"FLIGHT_ENDED reason {values[1]!r} is not an index into {END_REASONS}")
        timeouts = int(values[n]) if len(values) > n else 0  # recorded before the count was added: none known
        counts = {t: int(v) for t, v in zip(COUNTED_TOPICS, values[2:n])}
        counts.update({t: int(v) for t, v in zip(SENSOR_TOPICS, values[n + 1:])})
        return cls(float(values[0]), END_REASONS[code], counts, timeouts)


def lockstep_warning(timeouts: int) -> str | None:
    """What ``timeouts`` lockstep timeouts in a flight mean, in one sentence (``lander fly``'s summary and
    ``lander analyse`` both print it; ``FlightEnd.lockstep_timeouts``); None for none."""
    if not timeouts:
        return None
    return (f"the sim advanced past {timeouts} states without the autopilot's answer (lockstep timeouts): "
            "not the deterministic flight (was the machine starved of CPU?)")


def parse_end_on(text: str) -> tuple[str, ...]:
    """The phases of a comma-separated ``end_on`` value; ValueError naming a bad entry."""
    items = tuple(s.strip() for s in text.split(",") if s.strip())
    bad = [s for s in items if s not in END_ON_CHOICES]
    if bad:
        raise ValueError(f"{', '.join(bad)} not allowed; allowed: {', '.join(END_ON_CHOICES)} (comma-separated)")
    return items


def shortfalls(reference: dict[str, tuple[int, bool]], recorded: dict[str, int]) -> list[str]:
    """``"TOPIC got of n"`` for each topic (sorted) whose recorded count is below ``n``: messages
    published and missing. ``reference`` is ``{topic: (n, exact)}``."""
    return [f"{topic} {recorded.get(topic, 0)} of {n}" for topic, (n, _exact) in sorted(reference.items())
            if recorded.get(topic, 0) < n]


def surplus(reference: dict[str, tuple[int, bool]], recorded: dict[str, int]) -> list[str]:
    """``"TOPIC got of n"`` for each ``exact`` topic (sorted) recorded *more* often than ``n``: the
    bag holds messages its publishers did not send in this flight (another flight's in the same
    ROS domain, or a second epoch); not a missing message."""
    return [f"{topic} {recorded.get(topic, 0)} of {n}" for topic, (n, exact) in sorted(reference.items())
            if exact and recorded.get(topic, 0) > n]


#: The simulator's pause answer ends with this and the flight's number.
FLIGHT_SUFFIX = ", flight "
#: Start of the name of the simulator's ``DiagnosticStatus`` (``"lander_sim: simulation"``); the
#: autopilot reports on ``/diagnostics`` too.
SIM_REPORT_PREFIX = "lander_sim:"


def paused_flight(text: str) -> int | None:
    """The flight number in the simulator's pause answer (``"paused at t = T s (was running),
    flight N"``); None if it has none (a simulator from before the numbers)."""
    head, sep, n = text.rpartition(FLIGHT_SUFFIX)
    return int(n) if sep and n.isdigit() else None


def sim_report(msg: Any) -> dict[str, str] | None:
    """The simulator's status in a ``diagnostic_msgs/DiagnosticArray`` as ``{key: value}`` (rclpy's
    message or a bag reader's); None if the array has none."""
    for status in msg.status:
        if status.name.startswith(SIM_REPORT_PREFIX):
            return {kv.key: kv.value for kv in status.values}
    return None


def sim_paused(msg: Any) -> bool | None:
    """What a ``diagnostic_msgs/DiagnosticArray`` says of the simulator: whether it is paused (its
    ``paused`` value, :func:`sim_report`), None when the array holds no status of the simulator.
    Who watches a flight's state stream reads it to tell a paused flight from a lost stream."""
    report = sim_report(msg)
    return None if report is None else report.get("paused") == "True"


def format_matched(counts: dict[str, int]) -> str:
    """``/lander/subscribers``' answer: ``"topic=count"`` pairs separated by spaces."""
    return " ".join(f"{t}={n}" for t, n in counts.items())


def parse_matched(text: str) -> dict[str, int]:
    """Decode :func:`format_matched`; ValueError naming a malformed pair."""
    out: dict[str, int] = {}
    for pair in text.split():
        topic, sep, n = pair.partition("=")
        if not sep or not n.isdigit():
            raise ValueError(f"/lander/subscribers answered {pair!r}: expected topic=count")
        out[topic] = int(n)
    return out
