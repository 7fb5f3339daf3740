"""The sim node's gate: whether the simulation may advance, and what pause, resume and step do.

Plain Python, no rclpy. The node's lockstep wait, pause, ``pause_at`` hold and end instant are
one state machine; written as flags spread over the node's callbacks it was hard to see which
combinations could occur, so it lives here with named states (:class:`Mode`) and one method per
event (:class:`Event`), each unit-tested without the middleware (test/sim_node/test_gate.py).
The node feeds the gate every event and does what it answers: advance a tick or wait
(:meth:`Gate.poll`), publish the instant's state, hold it back or end the flight
(:meth:`Gate.ticked`), refuse a service (:meth:`Gate.refusal`) or publish a pending state
(:meth:`Gate.resume`, :meth:`Gate.advance`, :meth:`Gate.reset`).

The transitions (docs/sim_node.md, "The gate")::

    NOT_STARTED --resume--> RUNNING (publish state 1 and /clock)
    NOT_STARTED, HELD --step/run_until--> PAUSED (publish the pending state first)
    RUNNING --published (lockstep)--> AWAITING --answer / timeout--> RUNNING
    RUNNING, AWAITING --pause--> PAUSED --resume--> AWAITING if an answer is owed, else RUNNING
    RUNNING --tick reaches pause_at--> HELD --resume--> RUNNING (publish the held state)
    RUNNING, AWAITING, PAUSED --tick reaches the end--> ENDED --reset--> PAUSED
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

#: Float rounding of sim times compared against a requested instant (pause_at, end_time) [s].
TIME_EPS = 1e-9


class Mode(Enum):
    """Where the simulation is: whether it may advance and what the current instant has published."""

    #: Started paused (``start_paused``): nothing published yet; the first resume, step, run_until or
    #: reset publishes state 1 (and /clock).
    NOT_STARTED = "not started"
    #: Advancing a tick whenever the pacer says one is due.
    RUNNING = "running"
    #: Lockstep: the state just published waits for the controller's answer (or lockstep_timeout).
    AWAITING = "awaiting"
    #: Paused by the pause service or an already-reached pause_at; the current instant's state is out.
    PAUSED = "paused"
    #: Paused by a running tick reaching pause_at: /clock shows the instant, its state is held back
    #: until resume or step, so inputs given while held act from exactly that instant.
    HELD = "held"
    #: The end instant (end_time / end_on) is published: nothing advances until a reset or scene load.
    ENDED = "ended"

    @property
    def paused(self) -> bool:
        """Not advancing by itself: what the diagnostics' ``paused`` and the pause answer say."""
        return self not in (Mode.RUNNING, Mode.AWAITING)


class Event(Enum):
    """What changes the gate's mode: services, the node's loop and ticks, answers, parameters."""

    RESUME = "resume"
    PAUSE = "pause"
    STEP = "step"
    RUN_UNTIL = "run_until"
    RESET = "reset"  # the reset service or a scene load
    PUBLISHED = "published"  # a state went out
    ANSWER = "answer"  # a command answering the awaited state was accepted
    ANSWER_TIMEOUT = "answer timeout"  # lockstep_timeout of wall time passed without it
    PAUSE_AT_REACHED = "pause_at reached"
    END_REACHED = "end reached"
    PARAMETERS_CHANGED = "parameters changed"


class Publish(Enum):
    """What the node publishes after a transition, so that the current instant's state is out."""

    NOTHING = "nothing"
    #: The current instant's state; /clock already shows it (it was held back at pause_at).
    STATE = "state"
    #: The current instant's state and /clock (a reset, or the first state of a flight started paused).
    STATE_AND_CLOCK = "state and clock"


class TickOutcome(Enum):
    """What the node publishes after a tick advanced the physics."""

    PUBLISH = "publish"  # the new instant's state (and /clock)
    HOLD = "hold"  # /clock only: paused at pause_at, the state waits for resume or step
    END = "end"  # the state, then the end (a last /diagnostics and FLIGHT_ENDED); Gate.end_reason says why


class Refusal(Enum):
    """Why a service is refused in the current mode; :meth:`message` is the service's answer."""

    ENDED = "ended"
    NOT_PAUSED = "not paused"

    def message(self, t: float) -> str:
        """The answer text at sim time ``t`` (users and tests match it: keep it stable)."""
        if self is Refusal.ENDED:
            return f"the flight ended at t = {t!r} s; reset or load a scene to fly again"
        return "step needs a paused simulation: call /lander/pause first"


class GateError(RuntimeError):
    """An event the gate cannot take in its mode: a bug in its caller (the node), never bad input."""


@dataclass(frozen=True)
class GateSettings:
    """The node's parameters the gate reads (docs/sim_node.md, "Parameters")."""

    lockstep: bool = False
    lockstep_timeout: float = 1.0  # wall seconds [s]
    pause_at: float = -1.0  # sim time [s]; < 0: never
    end_time: float = -1.0  # sim time [s]; < 0: no time limit
    end_on: tuple[str, ...] = ()  # touchdown phases that end the flight ("landed", "crashed")


@dataclass(frozen=True)
class Poll:
    """The loop's answer: advance a tick now, or wait up to ``wait`` wall seconds for an event.

    ``timed_out`` is the state sequence whose lockstep answer just timed out (0: none); the node
    counts and logs it, then advances.
    """

    advance: bool
    wait: float = 0.0
    timed_out: int = 0


_ADVANCE = Poll(advance=True)
_IDLE = Poll(advance=False, wait=math.inf)  # paused: only an event (service, parameter) changes that


class Gate:
    """The lockstep / pause / end state machine of the sim node (see the module docstring).

    Besides :attr:`mode` it keeps the extended state the transitions read: the armed
    ``pause_at`` (consumed, set to -1, once reached), the state sequence whose answer lockstep
    waits for (kept through a pause: resume waits for it again, from the resume), and the end
    reason.
    """

    def __init__(self, settings: GateSettings, start_paused: bool) -> None:
        self.settings = settings
        self.mode = Mode.NOT_STARTED if start_paused else Mode.RUNNING
        #: Pause on reaching this sim time [s], once; < 0: not armed.
        self.pause_at = settings.pause_at
        #: Sequence of the published state whose answer lockstep waits for (0: none).
        self.awaited = 0
        #: Wall time [s] the wait for ``awaited`` (re)started: its publication, or the resume.
        self.awaited_since = 0.0
        #: Why the flight ended (``time-limit``, ``landed``, ``crashed``) once ENDED, else None.
        self.end_reason: str | None = None

    # --- queries -------------------------------------------------------------------------------

    def refusal(self, event: Event) -> Refusal | None:
        """Why the service ``event`` must be refused now (None: go ahead). Changes nothing.

        After the end only a reset moves the flight; a step needs a paused simulation (a running
        one has no instant to step from that the caller could know).
        """
        if event in (Event.RESUME, Event.STEP, Event.RUN_UNTIL) and self.mode is Mode.ENDED:
            return Refusal.ENDED
        if event is Event.STEP and not self.mode.paused:
            return Refusal.NOT_PAUSED
        return None

    def _pause_due(self, t: float) -> bool:
        return self.pause_at >= 0.0 and t >= self.pause_at - TIME_EPS

    def _end_reason(self, t: float, touchdown: str | None) -> str | None:
        if touchdown is not None and touchdown in self.settings.end_on:
            return touchdown
        if self.settings.end_time >= 0.0 and t >= self.settings.end_time - TIME_EPS:
            return "time-limit"
        return None

    # --- the node's loop and ticks -------------------------------------------------------------

    def poll(self, now: float, t: float) -> Poll:
        """May the running loop advance a tick from sim time ``t`` at wall time ``now``?

        Paused: wait for an event. A ``pause_at`` already reached (its state is out: set while
        past it, or passed by run_until) pauses here (PAUSE_AT_REACHED). Awaiting an answer: wait
        for it up to ``lockstep_timeout``, then advance anyway (ANSWER_TIMEOUT, reported once).
        """
        if self.mode.paused:
            return _IDLE
        if self._pause_due(t):
            self.mode, self.pause_at = Mode.PAUSED, -1.0
            return _IDLE
        if self.mode is Mode.AWAITING:
            waited = now - self.awaited_since
            if waited < self.settings.lockstep_timeout:
                return Poll(advance=False, wait=self.settings.lockstep_timeout - waited)
            timed_out, self.awaited, self.mode = self.awaited, 0, Mode.RUNNING
            return Poll(advance=True, timed_out=timed_out)
        return _ADVANCE

    def ticked(self, t: float, touchdown: str | None, honour_pause_at: bool) -> TickOutcome:
        """The physics reached sim time ``t`` (``touchdown``: the phase if no longer flying).

        The end (END_REACHED) wins over a pause_at at the same instant. ``honour_pause_at`` only
        for the running loop's ticks: step and run_until advance through pause_at (the loop pauses
        there afterwards if it is already passed, see :meth:`poll`).
        """
        if self.mode in (Mode.NOT_STARTED, Mode.HELD, Mode.ENDED):
            raise GateError(f"a tick in mode {self.mode.value!r}: its current instant is not published")
        reason = self._end_reason(t, touchdown)
        if reason is not None:
            self.mode, self.pause_at, self.end_reason, self.awaited = Mode.ENDED, -1.0, reason, 0
            return TickOutcome.END
        if honour_pause_at and self._pause_due(t):
            self.mode, self.pause_at = Mode.HELD, -1.0
            return TickOutcome.HOLD
        return TickOutcome.PUBLISH

    def published(self, seq: int, now: float) -> None:
        """State ``seq`` went out at wall time ``now``: in lockstep, its answer is awaited from now.

        Paused, the answer is still awaited (resume waits for it); after the end nothing is.
        """
        if self.mode in (Mode.NOT_STARTED, Mode.HELD):
            raise GateError(f"a state published in mode {self.mode.value!r}: publish only what the gate answered")
        if self.mode is Mode.ENDED or not self.settings.lockstep:
            return
        self.awaited, self.awaited_since = seq, now
        if self.mode is Mode.RUNNING:
            self.mode = Mode.AWAITING

    def answered(self, seq: int) -> None:
        """A command answering state ``seq`` was accepted (0: a command answering no state)."""
        if seq == 0 or seq != self.awaited:
            return
        self.awaited = 0
        if self.mode is Mode.AWAITING:
            self.mode = Mode.RUNNING

    # --- services and parameters ---------------------------------------------------------------

    def pause(self) -> Mode:
        """The pause service; returns the mode it found (the answer says whether it was running).

        Pausing publishes nothing: the current instant's state is already out, or is held / not
        started, and stays so.
        """
        was = self.mode
        if not was.paused:
            self.mode = Mode.PAUSED
        return was

    def resume(self, now: float) -> Publish:
        """The resume service (not refused, see :meth:`refusal`): run, publishing a pending state.

        A lockstep answer still owed is waited for again from ``now``, not from the pause.
        """
        if self.mode is Mode.ENDED:
            raise GateError("resume after the end: the node must refuse it (Gate.refusal)")
        was = self.mode
        self.mode = Mode.RUNNING
        if was is Mode.NOT_STARTED:
            return Publish.STATE_AND_CLOCK
        if was is Mode.HELD:
            return Publish.STATE
        if self.awaited:
            self.mode, self.awaited_since = Mode.AWAITING, now
        return Publish.NOTHING

    def advance(self) -> Publish:
        """Step or run_until accepted: the pending state goes out first (it is the step's start).

        A flight started paused or held at pause_at is then paused with its state out; a running
        one (run_until) stays running.
        """
        if self.mode is Mode.ENDED:
            raise GateError("step or run_until after the end: the node must refuse it (Gate.refusal)")
        if self.mode is Mode.NOT_STARTED:
            self.mode = Mode.PAUSED
            return Publish.STATE_AND_CLOCK
        if self.mode is Mode.HELD:
            self.mode = Mode.PAUSED
            return Publish.STATE
        return Publish.NOTHING

    def reset(self) -> Publish:
        """A reset or scene load: a new flight at its first instant, running if it was running.

        The awaited answer belongs to the old epoch and is forgotten; an armed pause_at stays armed.
        """
        self.mode = Mode.RUNNING if self.mode in (Mode.RUNNING, Mode.AWAITING) else Mode.PAUSED
        self.awaited, self.end_reason = 0, None
        return Publish.STATE_AND_CLOCK

    def parameters_changed(self, settings: GateSettings, changed: set[str] | frozenset[str]) -> None:
        """New parameter values; ``changed`` names the parameters set.

        ``pause_at`` is re-armed only when it is set (reaching it consumes it). Setting
        ``lockstep`` (on or off) forgets the awaited answer: lockstep waits from the next state.
        """
        self.settings = settings
        if "pause_at" in changed:
            self.pause_at = settings.pause_at
        if "lockstep" in changed:
            self.awaited = 0
            if self.mode is Mode.AWAITING:
                self.mode = Mode.RUNNING
