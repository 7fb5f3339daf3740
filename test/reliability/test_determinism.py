"""Determinism: in lockstep the same scene, parameters, controller and seed fly the same flight,
bit for bit, whatever the CPU load; the recorded bags carry byte-identical payloads.

Why exact equality is the right tolerance: in lockstep the sim advances only on the answer to
the state it published, every input is piecewise constant over a tick, and physics and controller
are pure functions of (state, input) evaluated in the same order with the same IEEE-754
operations. Wall time enters nowhere, so any difference at all, even one ulp, is a bug
(a missed answer, a timeout, a race at start-up), never "numerical noise".
"""
from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from lander_tools import stack_meter as meter

from .stack import START_TIMEOUT, Stack, Watch, raw_messages, stamp_s

SCENE = "hover-canted"  # scenario 7 with the seed-2 canted thrusters, its own autopilot
SEED = 7
#: Sim seconds per flight: 150 lockstep control periods of 0.1 s, in the controller's transient
#: (attitude and altitude moving, throttles varying). Bit-identity is a property of every single
#: step (any difference, once there, stays), so more steps add run time, not strength; the
#: one-hour soak covers length.
FLIGHT_S = 15.0
TOPICS = ("/lander/state", "/lander/throttle", "/autopilot/status")


def _fly_lockstep(stack: Stack, watch: Watch, bag: Path) -> None:
    """One flight with the sim, the autopilot and a recorder as separate processes, lockstep, speed 0.

    Start-up handshake (so the first tick cannot be advanced by a lockstep timeout): the sim starts
    paused; once everyone is discovered it is reset, and resumed only after its diagnostics show
    that it accepted the autopilot's answer to state 1 (both directions of the loop matched).
    """
    stack.sim(scene=SCENE, speed=0.0, lockstep=True, lockstep_timeout=5.0, start_paused=True, seed=SEED,
              diagnostics_rate=20.0)
    stack.autopilot(scene=SCENE, use_sim_time=True)
    stack.recorder(bag, TOPICS)
    # watch + autopilot + recorder on the state; watch + sim + recorder on the command.
    watch.wait_graph({"/lander/state": 3, "/lander/throttle": 3, "/autopilot/status": 2},
                     {"/lander/throttle": 2}, services=("reset", "resume"))
    from lander_ros.flight_span import parse_matched

    # Both writers matched their three readers before the closes below count (each poll waits for
    # the service's answer). The answers' side: without it a run under load recorded no answer to
    # the first 14 states of the flight (the recorder's throttle reader matched late). The states'
    # side: a CI run with a busy core saw the sim's state writer match the recorder only after the
    # six resets' 18 s (the recorder got no state). The closes then give the readers' side a
    # reset's time.
    deadline = time.monotonic() + START_TIMEOUT
    for service, topic, writer in (("autopilot_matched", "/lander/throttle", "the autopilot's throttle writer"),
                                   ("subscribers", "/lander/state", "the sim's state writer")):
        while parse_matched(watch.call(service).message).get(topic, 0) < 3:
            assert time.monotonic() < deadline, f"{writer} never matched its three readers"
    closed = 0
    for _attempt in range(6):
        n_thr = len(watch.throttles)
        accepted = int(watch.latest_diag().get("commands_accepted", 0))
        # A close counts only once the sim's state writer has matched all three readers (watch,
        # autopilot, recorder): a reader seen in the graph is not yet matched, and a state sent
        # before the match is not delivered (volatile).
        everyone = parse_matched(watch.call("subscribers").message).get("/lander/state", 0) >= 3
        assert watch.call("reset").success
        try:
            watch.wait_for(lambda: any(c.state_sequence == 1 for c in watch.throttles[n_thr:]), 3.0,
                           "the autopilot's answer to state 1")
            watch.wait_for(lambda: int(watch.latest_diag().get("commands_accepted", 0)) > accepted, 3.0,
                           "the sim accepting a command")
        except TimeoutError:
            continue  # a side not matched yet: reset again (state 1 is republished)
        closed += everyone
        if closed == 2:  # once more after that: the readers' side of the match has had a reset's time
            break
    else:
        raise AssertionError("the loop sim -> autopilot -> sim did not close twice in 6 resets")
    n0 = len(watch.states)
    assert watch.call("resume").success
    watch.wait_for(lambda: any(stamp_s(s.header.stamp) >= FLIGHT_S for s in watch.states[n0:]), START_TIMEOUT,
                   f"t >= {FLIGHT_S} s")
    stack.check_alive()
    diag = watch.latest_diag()
    # Autopilot first: in lockstep the sim then waits instead of running on.
    assert stack.stop("autopilot") == 0
    assert stack.stop("sim") == 0
    assert stack.stop("recorder") == 0
    assert diag["lockstep_timeouts"] == "0", diag
    # Gone from the graph, so that the next flight's discovery counts only its own processes.
    n = watch.node
    watch.wait_for(lambda: (n.count_subscribers("/lander/state"), n.count_subscribers("/lander/throttle"),
                            n.count_publishers("/lander/throttle")) == (1, 1, 1), START_TIMEOUT,
                   "the stopped processes leaving the graph")


def _flight(bag: Path) -> dict[str, list[bytes]]:
    """Raw payloads of the flight proper: states after the last reset up to FLIGHT_S, their answers.

    The epochs of the start-up handshake are told apart by content, never by the order in which
    the recorder heard two writers: the sim's states come from one writer, in order, so the flight
    proper starts at the last state 1; each earlier epoch had a state 1 only (the sim is paused
    after a reset), so every answer to a state other than 1 is the flight's, and every answer to
    state 1, from whichever epoch, answers the same state with the controller's memory cleared and
    must be byte-identical. Bag time cannot separate the epochs: reliable delivery orders one
    writer's samples, not two writers', and under load the recorder can hear the previous epoch's
    state 1 after this epoch's answer to it.
    """
    from lander_tools.bagio import read_bag

    st = read_bag(bag, ["/lander/state"]).topics["/lander/state"]
    start = max(i for i, m in enumerate(st.messages) if m.sequence == 1)
    msgs = raw_messages(bag, since={"/lander/state": int(st.t_bag_ns[start])})
    states = [(r, m) for r, m in msgs["/lander/state"] if stamp_s(m.header.stamp) <= FLIGHT_S]
    seqs = {m.sequence for _, m in states}
    np.testing.assert_array_equal(sorted(seqs), np.arange(1, len(states) + 1))  # nothing lost
    # The state that reaches FLIGHT_S may be the last one (`lander fly` stops the autopilot there).
    asked = {m.sequence for _, m in states if stamp_s(m.header.stamp) < FLIGHT_S - 1e-9}
    answers = [(r, m) for r, m in msgs.get("/lander/throttle", []) if m.state_sequence in asked]
    firsts = [r for r, m in answers if m.state_sequence == 1]
    assert firsts, f"no answer to state 1 in the bag ({len(answers)} answers to the flight's {len(asked)} states)"
    differing = sum(r != firsts[0] for r in firsts)
    assert differing == 0, f"{differing} of the {len(firsts)} answers to state 1 (one per reset) differ from the first"
    kept = next(i for i, (_, m) in enumerate(answers) if m.state_sequence == 1)
    answers = [a for i, a in enumerate(answers) if a[1].state_sequence != 1 or i == kept]
    answered = sorted(m.state_sequence for _, m in answers)
    missing, twice = sorted(asked - set(answered)), sorted({s for s in answered if answered.count(s) > 1})
    assert not missing and not twice, f"every state answered exactly once: unanswered {missing}, answered twice {twice}"
    # Status of the flight proper (after the first control period, up to the last state asked: the
    # autopilot is stopped once the state at FLIGHT_S is out, so whether it reported on that one is
    # a race, as for its answer): how many pre-reset states the autopilot answered while starting
    # (its `steps` counter, and a wall-clock "state lost" warning in last_error) depends on start-up
    # timing, not on the flight; everything else must match.
    status = [(r, m) for r, m in msgs["/autopilot/status"] if 0.0 < stamp_s(m.header.stamp) < FLIGHT_S - 1e-9]
    status_fields = [(m.header.stamp.sec, m.header.stamp.nanosec, m.controller, m.saturated, m.rejected,
                      m.throttles.tobytes()) for _, m in status]
    return {"state": [r for r, _ in states], "throttle": [r for r, _ in answers], "status": status_fields}


def test_two_lockstep_flights_under_cpu_load_are_bit_identical(stack: Stack, watch: Watch, tmp_path: Path,
                                                                busy_core: subprocess.Popen) -> None:
    flights = []
    for k in range(2):
        bag = tmp_path / f"run{k}"
        _fly_lockstep(stack, watch, bag)
        flights.append(_flight(bag))
    a, b = flights
    assert len(a["state"]) >= FLIGHT_S / 0.1  # one state per 0.1 s control period
    for topic in ("state", "throttle"):
        assert len(a[topic]) == len(b[topic]), f"{topic}: {len(a[topic])} messages in flight 1, {len(b[topic])} in flight 2"
        first = next((i for i, (x, y) in enumerate(zip(a[topic], b[topic])) if x != y), None)
        assert first is None, f"{topic} payloads differ from message {first} on"
    # The autopilot's status too, except the wall-clock text of start-up warnings (see docs/reliability.md).
    assert a["status"] == b["status"]


def _fly_cli(bag: Path, compose: bool) -> None:
    rc, out = meter.fly_recorded(SCENE, FLIGHT_S, compose, bag, timeout=180.0)
    assert rc == 0, out


def test_lander_fly_lockstep_answers_every_state_from_the_first(tmp_path: Path, busy_core: subprocess.Popen) -> None:
    """The user's path (``lander fly``, multi-process): a loss at start-up would make flights differ."""
    for k in range(2):
        bag = tmp_path / f"fly{k}"
        _fly_cli(bag, compose=False)
        f = meter.loop_figures(bag)
        assert (f.states_missing, f.commands_missing, f.lockstep_timeouts) == (0, 0, 0), f


def test_composed_and_multi_process_fly_the_same_flight(stack: Stack, watch: Watch, tmp_path: Path) -> None:
    """``lander fly --compose`` (one process, one executor) flies bit for bit what separate processes fly."""
    _fly_lockstep(stack, watch, tmp_path / "multi")
    multi = _flight(tmp_path / "multi")
    _fly_cli(tmp_path / "composed", compose=True)
    composed = _flight(tmp_path / "composed")
    for topic in ("state", "throttle"):
        n = min(len(multi[topic]), len(composed[topic]))
        assert n >= FLIGHT_S / 0.1
        assert multi[topic][:n] == composed[topic][:n], topic


# --- `lander fly` twice: every recorded topic, sim alone and lockstep ---------------------------

#: Recorded topics whose content is paced by the wall clock by design, so their number differs
#: between runs: /diagnostics (health at diagnostics_rate Hz of wall time, with wall-clock figures:
#: real-time factor, step time) and /lander/markers (at most marker_rate Hz of wall time, for RViz).
#: Their payloads are checked for what is deterministic in them: each marker's trajectory is a
#: prefix of the sim's positions, which the state payloads (compared exactly) already fix.
WALL_PACED = ("/diagnostics", "/lander/markers")
FLY_S = 5.0


def _payloads(bag: Path) -> dict[str, list[bytes]]:
    """Every message's serialised payload per topic, read with the independent `mcap` reader."""
    from mcap.reader import make_reader

    out: dict[str, list[bytes]] = {}
    (mcap,) = bag.glob("*.mcap")
    with open(mcap, "rb") as fh:
        for _schema, channel, message in make_reader(fh).iter_messages(log_time_order=False):
            out.setdefault(channel.topic, []).append(bytes(message.data))
    return out


def _mask_wall_paced_counts(payload: bytes) -> bytes:
    """A FlightEvent payload, with FLIGHT_ENDED's counts of WALL_PACED topics set to -1 (re-serialised);
    any other event unchanged."""
    from lander_ros.flight_span import COUNTED_TOPICS
    from lander_tools.bagio import lander_typestore

    ts = lander_typestore()
    name = "lander_interfaces/msg/FlightEvent"
    msg = ts.deserialize_cdr(payload, name)
    if msg.kind != 12:  # FLIGHT_ENDED
        return payload
    values = msg.values.copy()
    for topic in WALL_PACED:
        values[2 + COUNTED_TOPICS.index(topic)] = -1.0
    msg.values = values
    for topic in WALL_PACED:  # the detail says the same counts in words
        msg.detail = re.sub(rf"{re.escape(topic)} \d+", f"{topic} -1", msg.detail)
    return bytes(ts.serialize_cdr(msg, name))


def _wall_clock_health_masked(payload: bytes) -> bytes:
    """An AutopilotStatus payload with its wall-clock health fields blanked (re-serialised):
    ``state_ok`` and ``last_error`` come from the autopilot's watchdog (``state_timeout`` wall
    seconds: a lockstep pause longer than that reads as "state lost"), so they say how fast the
    machine was, not what was flown; every other field must match."""
    from lander_tools.bagio import lander_typestore

    ts = lander_typestore()
    name = "lander_interfaces/msg/AutopilotStatus"
    msg = ts.deserialize_cdr(payload, name)
    msg.state_ok, msg.last_error = True, ""
    return bytes(ts.serialize_cdr(msg, name))


def _decoded(topic: str, payload: bytes) -> object:
    """A recorded payload decoded with the bag's own types, for an assertion message."""
    from lander_tools.bagio import lander_typestore

    types = {"/autopilot/status": "lander_interfaces/msg/AutopilotStatus", "/lander/events": "lander_interfaces/msg/FlightEvent",
             "/lander/state": "lander_interfaces/msg/LanderState", "/lander/throttle": "lander_interfaces/msg/ThrottleCommand"}
    return lander_typestore().deserialize_cdr(payload, types[topic]) if topic in types else payload[:64]


def _start_up_report(payload: bytes) -> bool:
    """An autopilot status sent before its first state (its watchdog, after state_timeout wall
    seconds: whether one comes before the flight starts depends on the wall clock)."""
    from lander_tools.bagio import lander_typestore

    msg = lander_typestore().deserialize_cdr(payload, "lander_interfaces/msg/AutopilotStatus")
    return msg.steps == 0 and not msg.state_ok


def _fly_twice(tmp_path: Path, controller: str | None) -> tuple[dict[str, list[bytes]], dict[str, list[bytes]]]:
    import os

    from lander_tools.fly.phases import fly
    from lander_tools.fly.plan import FlightPlan
    from lander_tools.fly.summary import summary

    runs = []
    for k in range(2):
        plan = FlightPlan(scene=SCENE, controller=controller, duration=FLY_S, speed=0.0, record=tmp_path / f"run{k}",
                          sim_params={"seed": SEED})
        with open(os.devnull, "w") as devnull:
            result = fly(plan, out=devnull)
        assert result.exit_code == 0 and result.bag_check.startswith("complete"), summary(result)
        runs.append(_payloads(tmp_path / f"run{k}"))
    return runs[0], runs[1]


@pytest.mark.parametrize("mode", [pytest.param("alone", marks=pytest.mark.slow), "lockstep"])
def test_lander_fly_twice_gives_identical_payloads_on_every_recorded_topic(mode: str, tmp_path: Path) -> None:
    """Sim alone (free running at speed 0; with --runslow) and with the autopilot in lockstep: the
    same scene and seed, flown twice by `lander fly`, record byte-identical payloads on every topic
    whose content is a function of sim time (all but WALL_PACED), message for message; the
    autopilot's start-up reports (no state yet: wall-clock driven, before the flight) are left out."""
    controller = "none" if mode == "alone" else None
    a, b = _fly_twice(tmp_path / mode, controller)
    assert set(a) == set(b)
    for run in (a, b):  # FLIGHT_ENDED also counts the wall-paced topics: those two counts masked
        run["/lander/events"] = [_mask_wall_paced_counts(x) for x in run["/lander/events"]]
        if "/autopilot/status" in run:
            run["/autopilot/status"] = [_wall_clock_health_masked(x) for x in run["/autopilot/status"]
                                        if not _start_up_report(x)]
    for topic in sorted(set(a) - set(WALL_PACED)):
        assert len(a[topic]) == len(b[topic]), f"{mode}: {topic}: {len(a[topic])} vs {len(b[topic])} messages"
        first = next((i for i, (x, y) in enumerate(zip(a[topic], b[topic])) if x != y), None)
        assert first is None, (f"{mode}: {topic}: payloads differ from message {first} on: "
                               f"{_decoded(topic, a[topic][first])} vs {_decoded(topic, b[topic][first])}")
    assert len(a["/lander/state"]) == round(FLY_S / 0.1) + 1  # every control instant, t = 0 to the end
