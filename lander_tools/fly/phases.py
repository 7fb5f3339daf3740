"""``fly()``: a flight's six phases, each a function of its own, run in order (the package
docstring, :mod:`lander_tools.fly`, says what each does and why)."""
from __future__ import annotations

import math
import os
import secrets
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

import rclpy
from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

from lander_interfaces.srv import Reset
from lander_ros.flight_span import parse_matched, shortfalls, surplus
from lander_tools.fly.checks import check_plan, controllability_warning, scene_end_time, scene_label
from lander_tools.fly.domain import DomainTaken, FlightPlace, choose_place, write_run_file
from lander_tools.fly.flight import (
    Interrupted,
    LaunchedFlight,
    NodeDied,
    expected_publishers,
    expected_subscribers,
    reference_counts,
    strangers_in_graph,
)
from lander_tools.fly.plan import (
    ESTIMATE_TOPICS,
    EXIT_CRASHED,
    EXIT_ERROR,
    EXIT_INCOMPLETE_BAG,
    EXIT_INTERRUPTED,
    EXIT_OK,
    Action,
    FlightPlan,
    FlightResult,
    LaunchError,
)
from lander_tools.fly.processes import NodeProcess, node_commands, stop_all
from lander_tools.fly.summary import final_state
from lander_tools.fly.supervisor import MODE_LINES, STARTUP_TIMEOUT, Supervisor, call, sensor_topics, stall_reason
from lander_tools.fly.timeline import Stop, apply_now, arm, control_period, split_timeline
from lander_tools.live.bridge import command as live_command
from lander_tools.metrics_fit import scene_facts
from lander_tools.progress import Progress

#: Seconds [s] within which a stamp (whole nanoseconds) is the sim time it was made from.
STAMP_TOLERANCE = 1e-6
#: Wall seconds to wait for a lockstep autopilot's answer to state 1, and resets tried in all.
ANSWER_TIMEOUT = 5.0
RESET_ATTEMPTS = 3
#: Wall seconds to wait, after the sim announced the end, for the recorder to hold what it counted.
DELIVERY_TIMEOUT = 10.0
#: Wall seconds without a new state while the sim runs (without any word from it while it is
#: paused) after which the flight is an error (lander_tools.fly.supervisor.stall_reason).
STALL_TIMEOUT = 30.0
#: Wall seconds a start-up question to the sim stays unanswered before it is asked again (a
#: service request can be lost while discovery is still matching the reply's reader).
ASK_AGAIN = 2.0
#: Wall seconds between two looks at the graph for another flight's nodes while flying.
GRAPH_WATCH_PERIOD = 0.5


def fly(plan: FlightPlan, out: TextIO | None = None, progress: Any = None, env: dict[str, str] | None = None) -> FlightResult:
    """Fly ``plan`` to its end and return how it ended: the phases of the package docstring, in order.

    Must run in the main thread (it installs SIGINT/SIGTERM handlers for the duration).
    """
    out = out or sys.stdout
    if plan.duration is None:
        plan.duration = scene_end_time(plan.scene)  # the scene's own end.max_time, if it has one
    progress = progress or Progress(total=plan.duration)
    wall0 = time.monotonic()
    try:
        controller = check_plan(plan)
        place, lock = choose_place(os.environ if env is None else env, plan.domain, plan.network)
    except (LaunchError, ValueError) as exc:
        progress.finish()
        return FlightResult("error", EXIT_ERROR, 0.0, 0, str(exc))
    f = LaunchedFlight(plan, controller, out, progress, env, flight_id=secrets.token_hex(8), place=place)
    try:
        with (_signals_stop(f), _in_place(f, place), tempfile.TemporaryDirectory(prefix="lander-fly-") as folder):
            f.folder = Path(folder)
            result = _fly_phases(f)
    finally:
        lock.release()
    result.wall_time = time.monotonic() - wall0
    _add_what_was_watched(f, result)
    return result


def _fly_phases(f: LaunchedFlight) -> FlightResult:
    """Phases 1-5, then (however the flight ended) the nodes stopped, the bag closed and checked
    (phase 6) and this process's ROS side shut down."""
    result: FlightResult | None = None
    try:
        start_nodes(f)
        wait_until_matched(f)
        stops = reset_flight(f)
        run_to_end(f, stops)
        stop_nodes(f)
        result = _ended(f)
    except Interrupted:
        result = _failed(f, "interrupted", EXIT_INTERRUPTED, f"stopped by {f.stop_reason[0] if f.stop_reason else 'signal'}")
    except NodeDied as exc:
        result = _failed(f, "error", EXIT_ERROR, str(exc))
    except (LaunchError, ValueError, OSError) as exc:
        result = _failed(f, "error", EXIT_ERROR, str(exc))
    finally:
        f.progress.finish()
        if result is None:  # an unexpected exception is on its way out: still stop everything
            stop_all(f.procs)
        if result is not None:
            if not f.stopped:
                stop_nodes(f)
            close_and_check_bag(f, result)
        elif f.sup is not None and f.sup.recorder is not None:
            f.sup.recorder.close()
        if f.sup is not None:
            f.sup.node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    return result


@contextmanager
def _in_place(f: LaunchedFlight, place: FlightPlace) -> Iterator[None]:
    """The flight's ROS domain and discovery range in this process's environment (its own node)
    and the nodes' (``f.env``), and the run file that tells the user's verbs where it is, while
    the block runs; the environment as it was afterwards."""
    saved = {k: os.environ.get(k) for k in place.env()}
    os.environ.update(place.env())
    if f.env is not None:
        f.env = {**f.env, **place.env()}
    try:
        run_file: Path | None = write_run_file(place, f.plan.scene)
    except OSError:
        run_file = None  # the verbs then need ROS_DOMAIN_ID; the flight itself is unaffected
    try:
        yield
    finally:
        if run_file is not None:
            run_file.unlink(missing_ok=True)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextmanager
def _signals_stop(f: LaunchedFlight) -> Iterator[None]:
    """SIGINT and SIGTERM stop the flight (noted in ``f.stop_reason``; the next spin raises
    :class:`Interrupted`) while the block runs; the previous handlers afterwards."""

    def on_signal(signum: int, _frame: Any) -> None:
        f.stop_reason.append(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def start_nodes(f: LaunchedFlight) -> None:
    """Phase 1: this process's node (and recorder), then the node processes, paused."""
    assert f.folder is not None
    f.out.write(f"[fly] {f.place.describe()}\n")
    cmds = node_commands(f.plan, f.controller, f.folder, f.flight_id)
    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    f.sup = Supervisor(f.plan, f.controller, f.out, f.progress)
    f.executor = SingleThreadedExecutor()
    f.executor.add_node(f.sup.node)
    for name, argv in cmds.items():
        f.procs[name] = NodeProcess(name, argv, f.out, f.env)
    if f.plan.live is not None:  # `lander live` beside the nodes; counted in expected_subscribers
        f.procs["live"] = NodeProcess("live", live_command(f.plan.live, f.plan.live + 1 if f.plan.live else 0),
                                      f.out, f.env)
    f.out.write(
        f"[fly] scene {scene_label(f.plan.scene)}, controller {f.controller or 'none (sim alone)'}, "
        f"speed {f.plan.speed or 'max'}, pids " + ", ".join(f"{k} {p.pid}" for k, p in f.procs.items()) + "\n"
    )
    warning = controllability_warning(f.plan.scene, f.controller)
    if warning:
        f.out.write(f"[fly] {warning}\n")


def wait_until_matched(f: LaunchedFlight) -> None:
    """Phase 2: wait until every subscriber the flight needs is matched on every topic it needs.

    Asked from both ends: the sim's writers (``/lander/subscribers``), this process's readers
    (the recorder's and the launcher's own) and, with an autopilot, its state reader
    (``/autopilot/matched``). One more observer (a bridge process) is one more
    entry in :func:`~lander_tools.fly.flight.expected_subscribers`."""
    sup = f.sup
    assert sup is not None
    need_sim, need_here = expected_subscribers(f), expected_publishers(f)
    waiting: list[str] = []
    own_sim: list[bool] = []
    asked: list[tuple[Any, float]] = []  # the pending flight_id request and when it was sent

    def matched() -> bool:
        _refuse_if_taken(f, strangers_in_graph(f))
        waiting[:] = []
        if not own_sim:  # the simulator that answers must be this flight's (its flight_id)
            if not _sim_is_ours(f, asked):
                waiting.append("the sim's flight_id")
                return False
            own_sim.append(True)
        for topic, sub in sup.subs.items():
            if sub.get_publisher_count() < need_here.get(topic, 1):
                waiting.append(f"launcher <- {topic}")
        if sup.recorder is not None:
            for topic, n in need_here.items():
                if sup.recorder.wanted(topic) and sup.recorder.matched(topic) < n:
                    waiting.append(f"recorder <- {topic}")
        services = (sup.cli_subscribers, sup.cli_reset, sup.cli_resume)
        if waiting or not all(c.service_is_ready() for c in services):
            waiting.append("the sim's services")
            return False
        res = call(f.executor, sup.cli_subscribers, Trigger.Request(), STARTUP_TIMEOUT, "subscribers")
        have = parse_matched(res.message)
        waiting.extend(f"sim -> {t}" for t, n in need_sim.items() if have.get(t, 0) < n)
        if f.controller is not None and not waiting:
            # the other end of the state's match: the autopilot's reader has the sim's writer
            if not sup.cli_autopilot_matched.service_is_ready():
                waiting.append("the autopilot's services")
                return False
            res = call(f.executor, sup.cli_autopilot_matched, Trigger.Request(), STARTUP_TIMEOUT, "autopilot matched")
            have_ap = parse_matched(res.message)
            state_topic = ESTIMATE_STATE if f.plan.estimate else "/lander/state"
            if have_ap.get(f"sub:{state_topic}", 0) < 1:
                waiting.append(f"autopilot <- {state_topic}")
            # its first report goes out with its answer to state 1: its writer must have the readers
            readers = 1 + (sup.recorder is not None and sup.recorder.wanted("/diagnostics"))
            if have_ap.get("/diagnostics", 0) < readers:
                waiting.append("autopilot -> /diagnostics")
        if f.plan.estimate and not waiting:
            waiting.extend(_estimator_waits(f))
        return not waiting

    deadline = time.monotonic() + STARTUP_TIMEOUT
    while not matched():
        if time.monotonic() > deadline:
            raise LaunchError(f"nodes not matched within {STARTUP_TIMEOUT} s (still waiting for {', '.join(waiting)})")
        f.spin()


#: The estimate the autopilot flies on with ``--estimate``.
ESTIMATE_STATE = "/lander/estimate/state"


def _estimator_waits(f: LaunchedFlight) -> list[str]:
    """What the estimator node still waits for: its readers must have the sim's state and sensor
    writers (a volatile reader that has not matched a writer drops what it sends), its writers the
    autopilot's and the recorder's readers."""
    sup = f.sup
    assert sup is not None
    if not sup.cli_estimator_matched.service_is_ready():
        return ["the estimator's services"]
    res = call(f.executor, sup.cli_estimator_matched, Trigger.Request(), STARTUP_TIMEOUT, "estimator matched")
    have = parse_matched(res.message)
    waiting = [f"estimator <- {t}" for t in ("/lander/state", *sensor_topics(f.plan.scene))
               if have.get(f"sub:{t}", 0) < 1]
    for t in ESTIMATE_TOPICS:
        readers = (t == ESTIMATE_STATE and f.controller is not None) + (
            sup.recorder is not None and sup.recorder.wanted(t))
        if have.get(t, 0) < readers:
            waiting.append(f"estimator -> {t}")
    return waiting


def _sim_is_ours(f: LaunchedFlight, asked: list[tuple[Any, float]]) -> bool:
    """Whether the simulator answering ``flight_id`` is this flight's, asked without blocking: the
    request is sent (again after ASK_AGAIN s unanswered) and judged once answered, so that the graph
    is looked at between tries; another flight's simulator answering refuses the flight."""
    sup = f.sup
    assert sup is not None
    if not sup.cli_sim_get.service_is_ready():
        return False
    if not asked or (not asked[0][0].done() and time.monotonic() - asked[0][1] > ASK_AGAIN):
        asked[:] = [(sup.cli_sim_get.call_async(GetParameters.Request(names=["flight_id"])), time.monotonic())]
    fut = asked[0][0]
    if not fut.done():
        return False
    res = fut.result()
    theirs = res.values[0].string_value if res is not None and res.values else ""
    if theirs != f.flight_id:
        _refuse_if_taken(f, "a simulator of another flight answers")
    return True


def _refuse_if_taken(f: LaunchedFlight, what: str | None) -> None:
    """DomainTaken naming ``what`` (another flight's nodes seen), unless it is None."""
    if what is None:
        return
    f.refused = True
    raise DomainTaken(f.place.domain if f.place is not None else os.environ.get("ROS_DOMAIN_ID", "0"), what)


def _watch_graph(f: LaunchedFlight) -> None:
    """While flying: another flight's nodes appearing in the domain are said once, in one line."""
    sup = f.sup
    assert sup is not None
    if f.joined is not None:
        return
    what = strangers_in_graph(f)
    if what is not None:
        f.joined = (sup.t, what)
        f.out.write(f"[fly] another flight joined ROS_DOMAIN_ID={f.place.domain if f.place else '?'} at t = "
                    f"{sup.t:.2f} s ({what}): its messages are not this flight's; the sim refuses its throttles "
                    "and the bag check names what it added\n")


def reset_flight(f: LaunchedFlight) -> list[Stop]:
    """Phase 3: plan the timeline's stops and arm the first (``pause_at``); reset the sim (state 1
    at t = 0 goes to everyone matched), wait for that state (and, in lockstep, the autopilot's
    answer to it), apply the timeline's actions at t = 0. Returns the stops still to come.

    Everything that asks the sim something is done before the reset, so that the flight resumes
    right after it: a lockstep autopilot waiting long for its second state would report it lost."""
    sup, plan = f.sup, f.plan
    assert sup is not None
    stops: list[Stop] = []
    at_zero: list[Action] = []  # timed flights: actions of instant 0, put in force before the first step
    if sup.timed:
        stops, at_zero = split_timeline(sup.pending, control_period(f.executor, sup, plan), plan.duration)
        sup.pending = [a for a in sup.pending if a.kind == "throttle"]
        arm(f.executor, sup, stops[0].t if stops else -1.0)
    for attempt in range(1, RESET_ATTEMPTS + 1):
        sup.received.clear()  # counts of the flight: from its reset on
        sup.answered_first, sup.last_answer, states0 = False, 0, sup.states
        sup.last_status_t = -math.inf
        res = call(f.executor, sup.cli_reset, Reset.Request(), STARTUP_TIMEOUT, "reset")
        if not res.success:
            raise LaunchError(f"the sim refused the reset: {res.message}")
        f.wait_for(lambda: sup.states > states0, STARTUP_TIMEOUT,  # noqa: B023 - called within this attempt
                   "no state 1 from the simulator")
        try:
            f.wait_for(lambda: not sup.lockstep or sup.answered_first, ANSWER_TIMEOUT,
                       "no answer from the autopilot to state 1")
            break
        except LaunchError:
            # The sim's writer matched the autopilot's reader, but that reader had not yet matched
            # the writer (Fast DDS: a volatile reader then drops the sample). Resetting again asks
            # again; a recorder then holds both epochs, which the bag check reports (exit 3).
            if attempt == RESET_ATTEMPTS:
                raise
            f.out.write(f"[fly] the autopilot did not answer state 1 within {ANSWER_TIMEOUT} s: resetting again\n")
    for a in at_zero:
        apply_now(f.executor, sup, a, 0.0)  # in force (the autopilot took the demand) before the first step
    sup.apply_due()  # untimed flights: actions at t = 0 (e.g. a throttle override) before the first step
    return stops


def run_to_end(f: LaunchedFlight, stops: list[Stop]) -> None:
    """Phase 4: resume, apply the timeline at its stops, until the sim announces the end."""
    sup = f.sup
    assert sup is not None
    call(f.executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
    sup.last_state_wall = time.monotonic()
    next_look = time.monotonic()
    while sup.flight_end is None:
        if time.monotonic() >= next_look:
            next_look = time.monotonic() + GRAPH_WATCH_PERIOD
            _watch_graph(f)
        stalled = stall_reason(time.monotonic(), sup.last_state_wall, sup.sim_paused, sup.sim_word_wall, sup.t,
                               STALL_TIMEOUT)
        if stalled is not None:
            raise LaunchError(stalled)
        f.spin()
        sup.check_futures()
        if stops and sup.flight_end is None and sup.clock_t >= stops[0].t - 1e-6:
            stop = stops.pop(0)  # the sim stands at stop.t, its state not yet out
            for a in stop.actions:
                apply_now(f.executor, sup, a, stop.t)
            arm(f.executor, sup, stops[0].t if stops else -1.0)
            res = call(f.executor, sup.cli_resume, Trigger.Request(), STARTUP_TIMEOUT, "resume")
            if not res.success:  # the flight ended at this very instant (a touchdown): its event follows
                f.out.write(f"[fly] {res.message}\n")


def stop_nodes(f: LaunchedFlight) -> None:
    """Phase 5: once the recorder holds every message the sim counted (or after DELIVERY_TIMEOUT),
    stop the nodes, autopilot first, and take in what they flushed on their way out."""
    sup = f.sup
    f.stopped = True
    if sup is not None and sup.flight_end is not None:
        # Topics are not ordered among themselves: the end state may still be on its way here.
        published, end_t = sup.flight_end.counts, sup.flight_end.t
        rec = sup.recorder
        wanted = {t: n for t, n in published.items() if rec is not None and rec.wanted(t)}
        if f.plan.estimate:  # one estimate per state on each of the estimator's topics
            wanted.update({t: published["/lander/state"] for t in ESTIMATE_TOPICS if rec is not None and rec.wanted(t)})

        def delivered() -> bool:
            # In lockstep the autopilot answers the end state too, a command and then its status:
            # both belong to the flight (stopping the autopilot between the two loses the status).
            answered = not sup.lockstep or (sup.last_answer >= published["/lander/state"]
                                            and sup.last_status_t >= end_t - STAMP_TOLERANCE)
            # The states are counted where they are kept (the bag): this node's own watch
            # subscription may lose some on a loaded machine or a flat-out flight (it is the slower
            # reader), so waiting for it to count them all would run out the delivery timeout. The
            # watch needs the end state itself (the summary's last state); one reliable writer
            # delivers in order, so the latest state the watch holds is the highest.
            seen_end = sup.state is not None and sup.state.sequence >= published["/lander/state"]
            # What this node's watch received of the autopilot's status, the bag holds too.
            status = ({"/autopilot/status": sup.received.get("/autopilot/status", 0)}
                      if rec is not None and rec.wanted("/autopilot/status") else {})
            return answered and seen_end and all(rec is not None and rec.counts.get(t, 0) >= n
                                                 for t, n in (wanted | status).items())

        deadline = time.monotonic() + DELIVERY_TIMEOUT
        while not delivered() and time.monotonic() < deadline:
            f.executor.spin_once(timeout_sec=0.02)
    stop_all(f.procs)
    if sup is not None and sup.recorder is not None and f.executor is not None:
        # what the nodes flushed before they exited is still queued here
        sup.recorder.wait_quiet(0.2, 3.0, pause=lambda s: f.executor.spin_once(timeout_sec=s))


def close_and_check_bag(f: LaunchedFlight, result: FlightResult) -> None:
    """Phase 6: close the bag, print its counts and compare them with
    :func:`~lander_tools.fly.flight.reference_counts`;
    a missing message makes the result exit :data:`EXIT_INCOMPLETE_BAG` with a line naming it."""
    sup = f.sup
    if sup is None or sup.recorder is None:
        return
    if f.refused:  # whatever it holds is the other flight's
        sup.recorder.close()
        if f.plan.record is not None:
            shutil.rmtree(f.plan.record, ignore_errors=True)
        result.bag_check = "no bag: the flight was refused"
        return
    sup.recorder.writer.set_custom_data("outcome", result.outcome)
    counts = sup.recorder.close()
    result.counts, result.bag = counts, f.plan.record
    f.out.write(sup.recorder.summary() + "\n")
    if sup.flight_end is None:
        result.bag_check = "not checked: the flight did not reach its end"
        return
    reference = reference_counts(sup)
    missing, extra = shortfalls(reference, counts), surplus(reference, counts)
    checks = []
    if missing:
        checks.append("INCOMPLETE: " + ", ".join(missing) + " published")
    if extra:
        whose = ("another flight's" if f.joined is not None or sup.strangers
                 else "not published in this flight (another flight's, or a second start)")
        checks.append(f"EXTRA messages, {whose}: " + ", ".join(extra) + " published by this flight")
    elif f.joined is not None or sup.strangers:
        checks.append("another flight was in the domain (its messages on topics anyone may publish on, "
                      "e.g. /autopilot/status, cannot be told apart by their counts)")
    if missing or extra:
        if result.exit_code in (EXIT_OK, EXIT_CRASHED):
            result.exit_code = EXIT_INCOMPLETE_BAG
    if not missing:
        checks.insert(0, "complete: every message published in the flight is in it")
    result.bag_check = "; ".join(checks)


def _ended(f: LaunchedFlight) -> FlightResult:
    """The result of a flight that reached its end, as the sim announced it."""
    sup = f.sup
    assert sup is not None and sup.flight_end is not None
    end = sup.flight_end
    # the sim's count of the states it published (this node's watch may have lost some under load)
    states = end.counts.get("/lander/state", sup.states)
    result = FlightResult(end.reason, EXIT_CRASHED if end.reason == "crashed" else EXIT_OK, end.t, states)
    result.lockstep_timeouts = end.lockstep_timeouts
    return result


def _failed(f: LaunchedFlight, outcome: str, code: int, message: str) -> FlightResult:
    sup = f.sup
    return FlightResult(outcome, code, sup.t if sup else 0.0, sup.states if sup else 0, message)


def _add_what_was_watched(f: LaunchedFlight, result: FlightResult) -> None:
    """The last state, the touchdown's figures and the counted events' lines (the first of them
    were printed as they came)."""
    sup = f.sup
    if sup is None:
        return
    if sup.state is not None:
        result.final = final_state(sup.state, scene_facts({"scene": f.plan.scene}))
    result.touchdown = dict(sup.touchdown)
    result.controller, result.gains = sup.autopilot_gains
    result.touchdown_class = sup.touchdown_class
    if len(sup.gimbal_locks) > 1:
        ts = sup.gimbal_locks
        f.out.write(f"[fly] gimbal lock: {len(ts)} events in all, t = {ts[0]:.2f} to {ts[-1]:.2f} s "
                    "(only the first is shown)\n")
    if len(sup.mode_changes) > MODE_LINES:
        ts = sup.mode_changes
        f.out.write(f"[fly] mode changes: {len(ts)} in all, t = {ts[0]:.2f} to {ts[-1]:.2f} s "
                    f"(the first {MODE_LINES} are shown)\n")
