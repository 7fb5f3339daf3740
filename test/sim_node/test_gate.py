"""The sim node's gate (lander_sim.ros.gate), without the middleware: every (mode, event) pair.

The transition table below has one row per mode and event (a test checks it is complete); each
row reaches its mode through the gate's own events, delivers the event the way the node does
and checks the mode it leads to and what the gate answers. Guarded transitions (lockstep on or
off, an answer owed or not, pause_at armed or not) have a row per branch.
"""
from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import pytest

from lander_sim.ros.gate import (
    Event,
    Gate,
    GateError,
    GateSettings,
    Mode,
    Poll,
    Publish,
    Refusal,
    TickOutcome,
)

N, R, A, P, H, E = Mode.NOT_STARTED, Mode.RUNNING, Mode.AWAITING, Mode.PAUSED, Mode.HELD, Mode.ENDED
#: Sim time [s] at which the helper holds (pause_at) or ends (end_time) a flight.
T_MARK = 1.0
#: Wall time [s] of the helper's last published state (lockstep's wait starts there).
W0 = 100.0
TIMEOUT = 1.0


def gate_in(mode: Mode, *, lockstep: bool = False, owed: bool = False, pause_at: float = -1.0,
            end_time: float = -1.0, end_on: tuple[str, ...] = ()) -> Gate:
    """A gate brought into ``mode`` by its own events (so every mode is shown reachable).

    ``owed``: paused with the answer to state 1 still owed (lockstep). HELD and ENDED are reached
    by a tick at T_MARK; their own pause_at / end_time are then consumed or kept as the gate does.
    """
    settings = GateSettings(lockstep=lockstep or owed or mode is A, lockstep_timeout=TIMEOUT,
                            pause_at=pause_at, end_time=end_time, end_on=end_on)
    g = Gate(settings, start_paused=mode is N)
    if mode is N:
        pass
    elif mode in (R, A) or (mode is P and owed):
        g.published(1, W0)
        if mode is R:
            g.answered(1)
        elif mode is P:
            g.pause()
    elif mode is P:
        g.pause()
    elif mode is H:
        g.parameters_changed(replace(g.settings, pause_at=T_MARK), {"pause_at"})
        assert g.ticked(T_MARK, None, honour_pause_at=True) is TickOutcome.HOLD
        g.parameters_changed(replace(g.settings, pause_at=pause_at), {"pause_at"})
    elif mode is E:
        g.parameters_changed(replace(g.settings, end_time=T_MARK), set())
        assert g.ticked(T_MARK, None, honour_pause_at=False) is TickOutcome.END
        g.parameters_changed(replace(g.settings, end_time=end_time, pause_at=pause_at), {"pause_at"})
    assert g.mode is mode, (g.mode, mode)
    assert (g.awaited != 0) == (mode is A or owed)
    return g


def service(event: Event) -> Callable[[Gate], Any]:
    """The node's service handler, reduced to the gate: refused, or accepted and what to publish."""
    def act(g: Gate) -> Any:
        refusal = g.refusal(event)
        if refusal is not None:
            return refusal
        return g.resume(W0 + 5.0) if event is Event.RESUME else g.advance()
    return act


def lockstep_set(on: bool) -> Callable[[Gate], Any]:
    return lambda g: g.parameters_changed(replace(g.settings, lockstep=on), {"lockstep"})


def late_poll(t: float = 0.0) -> Callable[[Gate], Any]:
    """The loop polling long after the last state: an awaited answer has timed out."""
    return lambda g: g.poll(W0 + 10 * TIMEOUT, t)


@dataclass(frozen=True)
class Row:
    start: Mode
    event: Event
    case: str
    act: Callable[[Gate], Any]
    to: Mode | type[Exception]
    out: Any = None
    setup: dict[str, Any] = field(default_factory=dict)


IDLE = Poll(advance=False, wait=float("inf"))
ADV = Poll(advance=True)

TABLE: list[Row] = [
    # --- pause: answers the mode it found; publishes nothing ---
    Row(N, Event.PAUSE, "started paused stays so", lambda g: g.pause(), N, N),
    Row(R, Event.PAUSE, "running pauses", lambda g: g.pause(), P, R),
    Row(A, Event.PAUSE, "awaiting pauses, the answer still owed", lambda g: g.pause(), P, A),
    Row(P, Event.PAUSE, "paused stays", lambda g: g.pause(), P, P),
    Row(H, Event.PAUSE, "held stays held (its state still pending)", lambda g: g.pause(), H, H),
    Row(E, Event.PAUSE, "ended stays ended", lambda g: g.pause(), E, E),
    # --- resume ---
    Row(N, Event.RESUME, "first state and clock", service(Event.RESUME), R, Publish.STATE_AND_CLOCK),
    Row(R, Event.RESUME, "running: nothing", service(Event.RESUME), R, Publish.NOTHING),
    Row(A, Event.RESUME, "awaiting: the wait restarts", service(Event.RESUME), A, Publish.NOTHING),
    Row(P, Event.RESUME, "no answer owed: runs", service(Event.RESUME), R, Publish.NOTHING),
    Row(P, Event.RESUME, "answer owed: awaits it again", service(Event.RESUME), A, Publish.NOTHING, {"owed": True}),
    Row(H, Event.RESUME, "the held state (clock already out)", service(Event.RESUME), R, Publish.STATE),
    Row(E, Event.RESUME, "refused after the end", service(Event.RESUME), E, Refusal.ENDED),
    # --- step ---
    Row(N, Event.STEP, "first state and clock, then paused", service(Event.STEP), P, Publish.STATE_AND_CLOCK),
    Row(R, Event.STEP, "refused while running", service(Event.STEP), R, Refusal.NOT_PAUSED),
    Row(A, Event.STEP, "refused while awaiting", service(Event.STEP), A, Refusal.NOT_PAUSED),
    Row(P, Event.STEP, "steps from the published instant", service(Event.STEP), P, Publish.NOTHING),
    Row(H, Event.STEP, "the held state first, then paused", service(Event.STEP), P, Publish.STATE),
    Row(E, Event.STEP, "refused after the end", service(Event.STEP), E, Refusal.ENDED),
    # --- run_until (any mode but ended) ---
    Row(N, Event.RUN_UNTIL, "first state and clock, then paused", service(Event.RUN_UNTIL), P, Publish.STATE_AND_CLOCK),
    Row(R, Event.RUN_UNTIL, "running stays running", service(Event.RUN_UNTIL), R, Publish.NOTHING),
    Row(A, Event.RUN_UNTIL, "awaiting: run_until ignores lockstep", service(Event.RUN_UNTIL), A, Publish.NOTHING),
    Row(P, Event.RUN_UNTIL, "paused stays paused", service(Event.RUN_UNTIL), P, Publish.NOTHING),
    Row(H, Event.RUN_UNTIL, "the held state first, then paused", service(Event.RUN_UNTIL), P, Publish.STATE),
    Row(E, Event.RUN_UNTIL, "refused after the end", service(Event.RUN_UNTIL), E, Refusal.ENDED),
    # --- reset / load_scene: always state 1 and its clock ---
    Row(N, Event.RESET, "paused at the new start", lambda g: g.reset(), P, Publish.STATE_AND_CLOCK),
    Row(R, Event.RESET, "keeps running", lambda g: g.reset(), R, Publish.STATE_AND_CLOCK),
    Row(A, Event.RESET, "the old epoch's answer is forgotten", lambda g: g.reset(), R, Publish.STATE_AND_CLOCK),
    Row(P, Event.RESET, "stays paused, owed answer forgotten", lambda g: g.reset(), P, Publish.STATE_AND_CLOCK,
        {"owed": True}),
    Row(H, Event.RESET, "paused at the new start", lambda g: g.reset(), P, Publish.STATE_AND_CLOCK),
    Row(E, Event.RESET, "a new flight, paused", lambda g: g.reset(), P, Publish.STATE_AND_CLOCK),
    # --- a state published ---
    Row(N, Event.PUBLISHED, "nothing may publish before resume/step/reset", lambda g: g.published(2, W0), GateError),
    Row(R, Event.PUBLISHED, "free running: nothing awaited", lambda g: g.published(2, W0), R),
    Row(R, Event.PUBLISHED, "lockstep: its answer is awaited", lambda g: g.published(2, W0), A, None,
        {"lockstep": True}),
    Row(A, Event.PUBLISHED, "run_until in lockstep: the newest is awaited", lambda g: g.published(2, W0), A),
    Row(P, Event.PUBLISHED, "a step in lockstep: awaited on resume", lambda g: g.published(2, W0), P, None,
        {"lockstep": True}),
    Row(H, Event.PUBLISHED, "the held state goes out only through resume/step", lambda g: g.published(2, W0),
        GateError),
    Row(E, Event.PUBLISHED, "the end instant's state: nothing awaited", lambda g: g.published(2, W0), E, None,
        {"lockstep": True}),
    # --- the answer to state 1 accepted ---
    Row(N, Event.ANSWER, "nothing awaited", lambda g: g.answered(1), N),
    Row(R, Event.ANSWER, "nothing awaited", lambda g: g.answered(1), R),
    Row(A, Event.ANSWER, "answered: runs", lambda g: g.answered(1), R),
    Row(P, Event.ANSWER, "answered while paused: resume will not wait", lambda g: g.answered(1), P, None,
        {"owed": True}),
    Row(H, Event.ANSWER, "nothing awaited", lambda g: g.answered(1), H),
    Row(E, Event.ANSWER, "nothing awaited", lambda g: g.answered(1), E),
    # --- the loop polls after lockstep_timeout of wall time ---
    Row(N, Event.ANSWER_TIMEOUT, "paused: no timeout", late_poll(), N, IDLE),
    Row(R, Event.ANSWER_TIMEOUT, "nothing awaited: advance", late_poll(), R, ADV),
    Row(A, Event.ANSWER_TIMEOUT, "timed out: advance, reported once", late_poll(), R,
        Poll(advance=True, timed_out=1)),
    Row(P, Event.ANSWER_TIMEOUT, "paused: no timeout, still owed", late_poll(), P, IDLE, {"owed": True}),
    Row(H, Event.ANSWER_TIMEOUT, "held: no timeout", late_poll(), H, IDLE),
    Row(E, Event.ANSWER_TIMEOUT, "ended: no timeout", late_poll(), E, IDLE),
    # --- pause_at reached ---
    Row(N, Event.PAUSE_AT_REACHED, "not checked while paused", late_poll(t=2.0), N, IDLE, {"pause_at": 2.0}),
    Row(R, Event.PAUSE_AT_REACHED, "a running tick reaches it: state held",
        lambda g: g.ticked(2.0, None, honour_pause_at=True), H, TickOutcome.HOLD, {"pause_at": 2.0}),
    Row(R, Event.PAUSE_AT_REACHED, "found already reached (its state is out)", late_poll(t=2.0), P, IDLE,
        {"pause_at": 2.0}),
    Row(A, Event.PAUSE_AT_REACHED, "found already reached: paused, answer owed", late_poll(t=2.0), P, IDLE,
        {"pause_at": 2.0}),
    Row(P, Event.PAUSE_AT_REACHED, "a step passes it, not held",
        lambda g: g.ticked(2.0, None, honour_pause_at=False), P, TickOutcome.PUBLISH, {"pause_at": 2.0}),
    Row(H, Event.PAUSE_AT_REACHED, "not checked while held", late_poll(t=2.0), H, IDLE, {"pause_at": 2.0}),
    Row(E, Event.PAUSE_AT_REACHED, "not checked after the end", late_poll(t=2.0), E, IDLE, {"pause_at": 2.0}),
    # --- a tick reaches end_time ---
    Row(N, Event.END_REACHED, "no tick before the first state", lambda g: g.ticked(3.0, None, True), GateError,
        None, {"end_time": 3.0}),
    Row(R, Event.END_REACHED, "running ends", lambda g: g.ticked(3.0, None, True), E, TickOutcome.END,
        {"end_time": 3.0}),
    Row(A, Event.END_REACHED, "run_until in lockstep ends", lambda g: g.ticked(3.0, None, False), E, TickOutcome.END,
        {"end_time": 3.0}),
    Row(P, Event.END_REACHED, "a step ends", lambda g: g.ticked(3.0, None, False), E, TickOutcome.END,
        {"end_time": 3.0}),
    Row(H, Event.END_REACHED, "no tick while its state is held", lambda g: g.ticked(3.0, None, False), GateError,
        None, {"end_time": 3.0}),
    Row(E, Event.END_REACHED, "no tick after the end", lambda g: g.ticked(3.0, None, False), GateError, None,
        {"end_time": 3.0}),
    # --- lockstep set (on or off): the awaited answer is forgotten ---
    Row(N, Event.PARAMETERS_CHANGED, "lockstep on", lockstep_set(True), N),
    Row(R, Event.PARAMETERS_CHANGED, "lockstep on: waits from the next state", lockstep_set(True), R),
    Row(A, Event.PARAMETERS_CHANGED, "lockstep off: runs", lockstep_set(False), R),
    Row(A, Event.PARAMETERS_CHANGED, "lockstep set again: runs", lockstep_set(True), R),
    Row(P, Event.PARAMETERS_CHANGED, "owed answer forgotten", lockstep_set(True), P, None, {"owed": True}),
    Row(H, Event.PARAMETERS_CHANGED, "lockstep on", lockstep_set(True), H),
    Row(E, Event.PARAMETERS_CHANGED, "lockstep on", lockstep_set(True), E),
]


def test_the_table_has_a_row_for_every_mode_and_event():
    covered = {(row.start, row.event) for row in TABLE}
    missing = [(m.name, e.name) for m in Mode for e in Event if (m, e) not in covered]
    assert not missing, missing


@pytest.mark.parametrize("row", TABLE, ids=lambda r: f"{r.start.name}-{r.event.name}-{r.case}")
def test_transition(row: Row):
    g = gate_in(row.start, **row.setup)
    if isinstance(row.to, type):
        with pytest.raises(row.to):
            row.act(g)
        assert g.mode is row.start, "a refused event changes nothing"
        return
    out = row.act(g)
    assert g.mode is row.to
    assert out == row.out
    # The invariant the node relies on: awaiting exactly when running with an answer owed.
    assert (g.mode is A) == (not g.mode.paused and g.awaited != 0)
    if row.to is E:
        assert g.awaited == 0


# --- the extended state the table does not show --------------------------------------------------


def test_lockstep_waits_for_the_answer_then_times_out_once():
    g = gate_in(A)
    assert g.poll(W0 + 0.25, 0.0) == Poll(advance=False, wait=0.75)
    assert g.poll(W0 + TIMEOUT, 0.0) == Poll(advance=True, timed_out=1)
    assert g.poll(W0 + 2 * TIMEOUT, 0.0) == ADV, "a timeout is counted once per state"


def test_resume_restarts_the_lockstep_wait_from_the_resume_not_the_pause():
    g = gate_in(P, owed=True)
    assert g.resume(W0 + 50.0) is Publish.NOTHING
    assert g.poll(W0 + 50.5, 0.0) == Poll(advance=False, wait=0.5)


def test_only_the_answer_to_the_awaited_state_counts():
    g = gate_in(A)
    g.published(2, W0)
    g.answered(1)  # late answer to the previous state
    g.answered(0)  # a command answering no state (a person's throttle)
    assert g.mode is A and g.awaited == 2
    g.answered(2)
    assert g.mode is R and g.awaited == 0


def test_a_refusal_changes_nothing_and_its_message_is_the_service_answer():
    g = gate_in(E)
    assert g.refusal(Event.RESUME) is Refusal.ENDED and g.mode is E
    assert Refusal.ENDED.message(1.05) == "the flight ended at t = 1.05 s; reset or load a scene to fly again"
    assert Refusal.NOT_PAUSED.message(0.0) == "step needs a paused simulation: call /lander/pause first"
    assert gate_in(R).refusal(Event.PAUSE) is None and gate_in(R).refusal(Event.RESET) is None
    with pytest.raises(GateError):
        g.resume(W0)
    with pytest.raises(GateError):
        g.advance()


def test_pause_at_is_consumed_when_reached_and_re_armed_only_by_setting_it():
    g = gate_in(R, pause_at=2.0)
    assert g.ticked(1.98, None, honour_pause_at=True) is TickOutcome.PUBLISH
    assert g.ticked(2.0 - 1e-12, None, honour_pause_at=True) is TickOutcome.HOLD, "float rounding absorbed"
    assert g.pause_at < 0.0
    g.resume(W0)
    g.parameters_changed(replace(g.settings, lockstep_timeout=2.0), {"lockstep_timeout"})
    assert g.ticked(2.02, None, honour_pause_at=True) is TickOutcome.PUBLISH, "other parameters do not re-arm it"
    g.parameters_changed(replace(g.settings, pause_at=2.0), {"pause_at"})
    assert g.poll(W0, 2.02) == IDLE and g.mode is P, "set to an instant already passed: paused there"


def test_a_step_past_pause_at_pauses_on_the_next_resume():
    g = gate_in(P, pause_at=2.0)
    assert g.ticked(2.5, None, honour_pause_at=False) is TickOutcome.PUBLISH and g.pause_at == 2.0
    g.resume(W0)
    assert g.poll(W0, 2.5) == IDLE and g.mode is P and g.pause_at < 0.0


def test_the_end_wins_over_pause_at_at_the_same_instant_and_a_reset_keeps_pause_at_armed():
    g = gate_in(R, pause_at=3.0, end_time=3.0)
    assert g.ticked(3.0, None, honour_pause_at=True) is TickOutcome.END
    assert g.end_reason == "time-limit" and g.pause_at < 0.0
    g.reset()
    assert g.end_reason is None and g.mode is P
    h = gate_in(P, pause_at=3.0)
    h.reset()
    assert h.pause_at == 3.0


@pytest.mark.parametrize("touchdown, end_on, ends", [
    ("landed", ("landed",), True),
    ("crashed", ("landed", "crashed"), True),
    ("crashed", ("landed",), False),
    (None, ("landed", "crashed"), False),
])
def test_a_touchdown_ends_the_flight_only_when_listed_in_end_on(touchdown, end_on, ends):
    g = gate_in(R, end_on=end_on)
    out = g.ticked(5.0, touchdown, honour_pause_at=True)
    assert (out is TickOutcome.END) == ends
    assert g.end_reason == (touchdown if ends else None)


def test_modes_that_count_as_paused():
    assert [m for m in Mode if not m.paused] == [R, A]


def test_the_gate_imports_without_rclpy():
    code = "import sys, lander_sim.ros.gate; sys.exit('rclpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
