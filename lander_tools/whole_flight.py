"""``lander record --whole-flight``: record a flight that is already running, whole.

A recorder that joins a running flight can only hold it from the moment it is matched. To keep
the project's definition of a flight's span (docs/flying.md, "A flight's span": the first
recorded state is state 1 at t = 0, the last is the end instant, every message the simulator
published in between is in the bag) the recorder restarts the flight, the same way ``lander fly``
starts one, but from outside:

1. **find** the simulator (``/lander_sim``) within ``--wait`` s; a flight flown by ``lander fly``
   (its ``/lander_fly`` node resets, paces and ends the flight itself) is refused: record it with
   ``lander fly --record``;
2. **match from both ends**: the recorder's readers have matched every publisher of each recorded
   simulator topic, and the simulator's writers (``/lander/subscribers``) count one more reader
   than before the recorder existed (and one more on ``/lander/events``: this command's watch);
   the autopilot's state reader (of ``/lander/state``, or of the estimate it flies on) has its
   writer, and with an estimator node (``/lander_estimator``) its readers have the simulator's state
   and sensor writers and the recorder's readers have its estimate writers (recorded by default);
3. **pause** the flight (the answer says whether it was running) and let what was in flight
   arrive; the recorder drops all of it (it is *held*);
4. with ``--duration S``, set the simulator's ``end_time`` to S (the sim stops itself there);
5. **reset**: release the recorder, reset the flight (state 1 at t = 0 goes to everyone matched),
   and resume it if it was running (a paused flight stays paused: whoever paused it resumes it);
6. **record to the end**: at the simulator's ``FLIGHT_ENDED`` wait until the recorder holds as
   many messages as the simulator counted on each of its topics (and, with an estimator, one
   estimate per state on each estimate topic: the estimator restarts its filter at the reset's
   state 1), close the bag and compare, exit 3 with a line per short topic. Without an end (no
   ``end_time`` / ``end_on`` on the sim and no ``--duration``), record until Ctrl-C / SIGTERM or
   until the simulator leaves, and say that the bag was not checked.

Exit status: 0 the bag holds the whole flight (or was stopped before an end, unchecked), 1 no
flight / a flight this command must not restart / a refusal by the simulator, 2 bad options,
3 a message is missing from the bag.

``/diagnostics`` is the one simulator topic published while paused (wall-paced): one sent just
before the reset can arrive after the recorder is released. The recorder drops it by the flight
number it carries (the pause answer gives the old flight's). A CI run on 2 cores once recorded such
a report before the numbers (``/diagnostics 2 of 1``, exit 3).
"""
from __future__ import annotations

import argparse
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lander_tools.fly.plan import ESTIMATE_TOPICS

#: Exit statuses (``lander fly`` uses 3 for an incomplete bag too).
EXIT_OK, EXIT_FLIGHT, EXIT_USAGE, EXIT_INCOMPLETE_BAG = 0, 1, 2, 3
#: Wall seconds for the recorder and the simulator to match each other once the simulator is found.
MATCH_TIMEOUT = 30.0
#: Wall seconds without a message from the paused flight (other than /diagnostics) before the reset.
QUIET = 0.3
#: Wall seconds at most to wait for that quiet.
QUIET_LIMIT = 5.0
#: Wall seconds to wait, after FLIGHT_ENDED, for the recorder to hold what the simulator counted.
DELIVERY_TIMEOUT = 10.0
LAUNCHER_NODE = "/lander_fly"


class _Refused(Exception):
    """The flight cannot be recorded whole (the message says why); exit 1."""


def _say(text: str) -> None:
    print(f"lander record: {text}", flush=True)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """This command's options, beside the recorder's (:func:`lander_tools.recorder.build_parser`)."""
    parser.add_argument("--whole-flight", action="store_true",
                        help="record the running flight whole: once matched, restart it from t = 0 (its reset), "
                             "record to its end instant and check the bag against what the simulator published "
                             "(exit 3 if a message is missing); docs/flying.md")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="with --whole-flight: end the flight at this sim time [s] (sets the sim's end_time)")
    parser.add_argument("--start", action="store_true",
                        help="with --whole-flight: resume the flight after its reset even if it was paused "
                             "(a simulator started paused waits for everyone to be matched: the launch file)")
    parser.add_argument("--wait", type=float, default=10.0, metavar="S",
                        help="with --whole-flight: wall seconds to wait for the flight's simulator (default 10)")


def record_whole_flight(args: argparse.Namespace, on_started: Callable[[], None] | None = None) -> int:
    """Run the protocol of the module docstring with ``args`` from :func:`lander_tools.recorder.build_parser`
    and :func:`add_arguments`.

    ``on_started``: called once the flight has been reset (``lander record --live`` starts its
    bridge there, so the bridge's readers do not count among the ones this command waits for)."""
    from lander_tools.recorder import DEFAULT_TOPICS, RecorderConfig, RecorderError

    if args.duration is not None and not args.duration > 0.0:
        print(f"lander record: --duration must be > 0 s, got {args.duration}", file=sys.stderr)
        return EXIT_USAGE
    if args.stop_when_gone:
        print("lander record: --stop-when-gone is implied by --whole-flight (it ends with the flight)", file=sys.stderr)
        return EXIT_USAGE
    try:
        config = RecorderConfig(Path(args.output), args.storage, tuple(args.topics) or DEFAULT_TOPICS, bool(args.all),
                                meta={"whole_flight": "true"})
    except RecorderError as exc:
        print(f"lander record: {exc}", file=sys.stderr)
        return EXIT_USAGE

    from lander_tools.live.link import NoFlight

    stop = threading.Event()
    old = {s: signal.signal(s, lambda _n, _f: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _record(args, config, stop, on_started)
    except (NoFlight, TimeoutError, _Refused) as exc:
        print(f"lander record: {exc}", file=sys.stderr)
        return EXIT_FLIGHT
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def _record(args: argparse.Namespace, config: Any, stop: threading.Event,
            on_started: Callable[[], None] | None) -> int:
    from std_srvs.srv import Trigger

    from lander_ros.flight_span import (
        COUNTED_TOPICS,
        SENSOR_TOPICS,
        FlightEnd,
        parse_matched,
        paused_flight,
        shortfalls,
        surplus,
    )
    from lander_tools.live.link import AUTOPILOT_NODE, ESTIMATOR_NODE, SIM_NODE, FlightLink, NoFlight
    from lander_tools.recorder import Recorder

    with FlightLink("lander_record_whole") as link:
        link.wait_for_node(SIM_NODE, args.wait)
        _refuse_a_launched_flight(link)

        def sim_matched() -> dict[str, int]:
            return parse_matched(link.call(Trigger, "/lander/subscribers", Trigger.Request()).message)

        config.meta.update(_flight_meta(link))
        if not args.topics and not args.all:
            # an estimator's outputs beside the truth, as `lander fly --estimate` records them (recorded
            # only if published, as the sensors' topics)
            config.topics = tuple(dict.fromkeys((*config.topics, *ESTIMATE_TOPICS)))
        if config.meta["lockstep"] == "True" and config.meta["controller"] == "none":
            # a lockstep sim waits for an autopilot: give it the discovery time the simulator had
            try:
                link.wait_for_node(AUTOPILOT_NODE, args.wait)
                config.meta["controller"] = _controller(link)
            except NoFlight:
                _say(f"the simulator is in lockstep but no {AUTOPILOT_NODE} appeared within {args.wait:g} s")
        # 2. who the sim's writers had matched before this command's readers existed
        before = sim_matched()
        rec = Recorder(link.context, config, hold=True)
        try:
            ends: list[Any] = []

            def on_event(msg: Any) -> None:
                if msg.kind == msg.FLIGHT_ENDED:
                    ends.append(FlightEnd.from_values(list(msg.values)))

            link.subscribe("/lander/events", "lander_interfaces/msg/FlightEvent", on_event, depth=1000)
            # the sensors' topics the sim publishes (a scene with sensors) are in its answer
            sim_topics = [t for t in (*COUNTED_TOPICS, *(t for t in SENSOR_TOPICS if t in before)) if rec.wanted(t)]
            need = {t: before.get(t, 0) + 1 for t in sim_topics}
            need["/lander/events"] = before.get("/lander/events", 0) + 1 + ("/lander/events" in sim_topics)
            _wait_matched(link, rec, need, sim_topics, sim_matched, stop)
            # by now every reader of the state the sim has matched is known by its node's name: an
            # estimator node (it reads the state) is in the graph if it is in the flight
            estimates: list[str] = []
            if ESTIMATOR_NODE in link.node_names():
                _wait_matched(link, rec, need, sim_topics, sim_matched, stop)  # its ends too, whenever it was seen
                estimates = [t for t in ESTIMATE_TOPICS if rec.wanted(t)]
                # its initial-error seed, for the re-run of `lander analyse` (-1: the scene's sensors.seed)
                rec.writer.set_custom_data("seed", str(link.get_parameters(ESTIMATOR_NODE, ["seed"]).get("seed")))
            # /lander/events has other publishers (the autopilot): the sim's count is then a floor
            shared = {t for t in sim_topics if len(link.node.get_publishers_info_by_topic(t)) > 1}

            _refuse_a_launched_flight(link)  # again: by now every participant has been discovered
            # 3. pause and let the old flight's messages arrive (dropped: the recorder is held)
            paused = link.sim_service("pause")
            if not paused.ok:
                raise _Refused(f"the simulator refused to pause: {paused.message}")
            was_running = "(was running)" in paused.message
            # 3. ... nothing but the wall-paced /diagnostics coming in for QUIET s (the recorder drops it all)
            rec.wait_quiet(QUIET, QUIET_LIMIT, skip=("/diagnostics",))
            # 4. the end instant
            if args.duration is not None:
                out = link.set_parameters(SIM_NODE, {"end_time": float(args.duration)})
                if not out.ok:
                    raise _Refused(f"the simulator refused end_time {args.duration}: {out.message}")
            end = link.get_parameters(SIM_NODE, ["end_time", "end_on"])
            ends_at = _describe_end(end.get("end_time"), end.get("end_on"))
            # 5. restart the flight with the recorder writing; a report of the old flight sent just
            #    before the reset may still arrive: dropped by its flight number
            old = paused_flight(paused.message)
            if old is not None and "/diagnostics" in sim_topics:
                rec.accept["/diagnostics"] = _not_of_flight(old)
            rec.held.clear()
            reset = link.sim_service("reset")
            if not reset.ok:
                raise _Refused(f"the simulator refused the reset: {reset.message}")
            running = was_running or args.start
            if running:
                link.sim_service("resume")
            _say(f"recording {config.output} from the flight's reset (t = 0, {'running' if running else 'paused'}); "
                 f"{ends_at}")
            if on_started is not None:
                on_started()
            # 6. to the end
            while not ends and not stop.wait(0.05):
                if SIM_NODE not in link.node_names():
                    _say(f"{SIM_NODE} left the graph: closing the bag")
                    break
            flight_end = ends[0] if ends else None
            if flight_end is not None:
                _say(flight_end.detail())
                _wait_delivered(rec, {t: flight_end.counts.get(t, 0) for t in sim_topics}
                                | dict.fromkeys(estimates, flight_end.counts.get("/lander/state", 0)))
        except BaseException:
            counts = rec.close()
            if not any(counts.values()):  # held all along: an empty bag would only mislead
                shutil.rmtree(config.output, ignore_errors=True)
            raise
        if flight_end is not None:
            rec.writer.set_custom_data("outcome", flight_end.reason)  # as `lander fly` writes it
        counts = rec.close()
        print(rec.summary())
        if flight_end is None:
            _say("bag not checked: the flight did not reach its end while recording")
            return EXIT_OK
        reference = {t: (flight_end.counts.get(t, 0), t not in shared) for t in sim_topics}
        # the estimator answers every state of the restarted flight with one estimate on each topic
        reference.update(dict.fromkeys(estimates, (flight_end.counts.get("/lander/state", 0), True)))
        short, extra = shortfalls(reference, counts), surplus(reference, counts)
        if short:
            _say("INCOMPLETE: " + ", ".join(short) + " published")
            return EXIT_INCOMPLETE_BAG
        if extra:
            _say("EXTRA messages, not published by this flight's simulator (another flight's?): " + ", ".join(extra))
            return EXIT_INCOMPLETE_BAG
        _say(f"complete: the whole flight, t = 0 to {flight_end.t!r} s ({flight_end.reason}), "
             "every message the simulator published is in it")
        return EXIT_OK


def _not_of_flight(old: int) -> Callable[[bytes], bool]:
    """A recorder test of raw ``/diagnostics``: False for the simulator's report of flight ``old``."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    from lander_ros.flight_span import sim_report

    def test(data: bytes) -> bool:
        report = sim_report(deserialize_message(data, DiagnosticArray))
        # not the simulator's (the autopilot's): the sim's count does not cover it
        return report is None or report.get("flight") != str(old)

    return test


def _refuse_a_launched_flight(link: Any) -> None:
    if LAUNCHER_NODE in link.node_names():
        raise _Refused(f"this flight is flown by `lander fly` (node {LAUNCHER_NODE}), which resets and ends it "
                       "itself; record it with `lander fly ... --record BAG`")


def _flight_meta(link: Any) -> dict[str, str]:
    """The bag's custom data, as ``lander fly`` writes it: scene, speed and controller ("none"
    without an autopilot node), read from the running nodes' parameters; and the sim's lockstep."""
    from lander_tools.live.link import AUTOPILOT_NODE, SIM_NODE

    sim = link.get_parameters(SIM_NODE, ["scene", "speed", "lockstep"])
    meta = {k: str(sim.get(k)) for k in ("scene", "speed", "lockstep")}
    meta["controller"] = _controller(link) if AUTOPILOT_NODE in link.node_names() else "none"
    return meta


def _controller(link: Any) -> str:
    from lander_tools.live.link import AUTOPILOT_NODE

    return str(link.get_parameters(AUTOPILOT_NODE, ["controller"]).get("controller"))


def _wait_matched(link: Any, rec: Any, need: dict[str, int], sim_topics: list[str],
                  sim_matched: Callable[[], dict[str, int]], stop: threading.Event) -> None:
    """Step 2: spin until both ends are matched; TimeoutError naming what is still waiting.

    The recorder's readers: every publisher the graph shows on each recorded topic (the sim's
    topics at least one), with an autopilot node its throttles and status, with an estimator node
    its recorded estimate topics. The other ends: the sim's writers (``need``, from
    ``/lander/subscribers``), the autopilot's state reader (``/autopilot/matched``: of the truth or of the estimate, whichever it
    flies on) and the estimator's state and sensor readers (``/lander_estimator/matched``), so that
    state 1 of the reset and its readings reach them too."""
    from std_srvs.srv import Trigger

    from lander_ros.flight_span import parse_matched
    from lander_tools.live.link import AUTOPILOT_NODE, ESTIMATOR_NODE

    deadline = time.monotonic() + MATCH_TIMEOUT
    waiting: list[str] = []
    while True:
        autopilot = AUTOPILOT_NODE in link.node_names()
        estimator = ESTIMATOR_NODE in link.node_names()
        floor = dict.fromkeys(sim_topics, 1)
        if estimator:
            floor.update({t: 1 for t in ESTIMATE_TOPICS if rec.wanted(t)})
        if autopilot:
            floor.update({t: 1 for t in ("/lander/throttle", "/autopilot/status") if rec.wanted(t)})
        topics = set(floor) | {t for t, _ in link.node.get_topic_names_and_types() if rec.wanted(t)}
        waiting = [f"recorder <- {t}" for t in sorted(topics)
                   if rec.matched(t) < max(floor.get(t, 0), len(link.node.get_publishers_info_by_topic(t)))]
        if not waiting:
            have = sim_matched()
            waiting = [f"sim -> {t}" for t, n in need.items() if have.get(t, 0) < n]
            # every reader of the state the sim has matched, known here by its node's name: then
            # the graph has discovered whoever flies this flight (a `lander fly` is refused)
            named = [i for i in link.node.get_subscriptions_info_by_topic("/lander/state")
                     if i.node_name and not i.node_name.startswith("_NODE_NAME_UNKNOWN")]
            if len(named) < have.get("/lander/state", 0):
                waiting.append("the names of the state's readers")
        if not waiting and autopilot:
            answer = parse_matched(link.call(Trigger, "/autopilot/matched", Trigger.Request()).message)
            # one state reader: sub:/lander/state, or sub:/lander/estimate/state flying on the estimate
            waiting += [f"autopilot <- {k[4:]}" for k, n in answer.items() if k.startswith("sub:") and n < 1]
        if not waiting and estimator:
            answer = parse_matched(link.call(Trigger, f"{ESTIMATOR_NODE}/matched", Trigger.Request()).message)
            waiting += [f"estimator <- {k[4:]}" for k, n in answer.items() if k.startswith("sub:") and n < 1]
        if not waiting:
            return
        if time.monotonic() > deadline or stop.is_set():
            raise TimeoutError(f"not matched with the flight within {MATCH_TIMEOUT:g} s (still waiting for "
                               f"{', '.join(waiting)})")
        time.sleep(0.05)


def _wait_delivered(rec: Any, published: dict[str, int]) -> None:
    """Step 6: until the recorder holds what the simulator counted (bounded), then a short quiet
    for what others answered to the end state (the autopilot's throttles and status)."""
    deadline = time.monotonic() + DELIVERY_TIMEOUT
    while time.monotonic() < deadline and any(rec.counts.get(t, 0) < n for t, n in published.items()):
        time.sleep(0.02)
    rec.wait_quiet(QUIET, max(0.0, deadline - time.monotonic()) + QUIET)


def _describe_end(end_time: Any, end_on: Any) -> str:
    """How the flight will end, in words, from the simulator's ``end_time`` / ``end_on``."""
    parts = []
    if end_time is not None and float(end_time) >= 0.0:
        parts.append(f"t = {float(end_time):g} s")
    if end_on:
        parts.append(f"touchdown ({end_on})")
    if not parts:
        return "no end set on the simulator: recording until Ctrl-C (give --duration S for a checked bag)"
    return "the flight ends at " + " or ".join(parts)
