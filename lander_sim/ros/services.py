"""The simulator's services: load a scene, reset, pause, resume, step, run until, the parachute,
the stabiliser, and who is matched (docs/sim_node.md, "Services").

Each handler checks its request, asks the gate (:mod:`lander_sim.ros.gate`) whether the event is
allowed, and drives the node through the public methods of :class:`SimControl`. A refused request
answers ``success = false`` with one line saying what was wrong, and is counted and announced as
an ``INPUT_REJECTED`` event of kind ``service.<name>`` (the node's :meth:`SimControl.reject`);
the simulation is untouched.

No rclpy here: the node creates the ROS services from :meth:`SimServices.table` and passes each
request and response object in.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, Protocol

from std_srvs.srv import SetBool, Trigger

from lander_interfaces.srv import LoadScene, Reset, RunUntil, StepSimulation
from lander_ros.flight_span import FLIGHT_SUFFIX, format_matched
from lander_sim.errors import InputError
from lander_sim.ros.gate import Event, Gate, Publish
from lander_sim.ros.pacing import Pacer
from lander_sim.ros.sim_adapter import SimAdapter
from lander_sim.scenes import SceneError

#: A service handler: (request, response) -> the response, filled in.
Handler = Callable[[Any, Any], Any]


class SimControl(Protocol):
    """What the services need of the simulation node."""

    sim: SimAdapter
    gate: Gate
    pacer: Pacer

    #: The flight's number: 0 the node's first, one more at each reset or scene load.
    flight: int

    @property
    def steps_per_tick(self) -> int:
        """Physics steps in one control tick."""

    def reject(self, kind: str, detail: str) -> None:
        """Count, log and announce one rejected input."""

    def load(self, name: str) -> SimAdapter:
        """Build the simulation of scene ``name`` with the node's overrides."""

    def apply_stabiliser(self, sim: SimAdapter) -> None:
        """Apply the node's ``stabiliser`` parameter to ``sim``."""

    def start_flight(self) -> None:
        """Node-side state after a reset or a new scene; publishes the reset instant as state 1."""

    def publish_pending(self, what: Publish) -> None:
        """Publish what the gate answered."""

    def advance(self, n_steps: int, stop_on_touchdown: bool = False) -> None:
        """Advance ``n_steps`` physics steps now, publishing at every tick boundary."""

    def check_subscribers(self, now: float) -> None:
        """Re-read who listens to the optional outputs."""

    def publish_core_events(self) -> None:
        """Publish the core's pending events."""

    def report_now(self) -> None:
        """Publish a /diagnostics report now (its ``paused`` value among them)."""

    def matched(self) -> dict[str, int]:
        """Subscriptions matched by each output, publishers matched by each input (``sub:TOPIC``)."""


class SimServices:
    """The handlers of the simulator's services, over a :class:`SimControl`."""

    def __init__(self, node: SimControl) -> None:
        self.node = node

    def table(self) -> tuple[tuple[Any, str, Handler], ...]:
        """(service type, name, handler) of every service the simulator offers."""
        return (
            (LoadScene, "/lander/load_scene", self.load_scene),
            (Reset, "/lander/reset", self.reset),
            (Trigger, "/lander/pause", self.pause),
            (Trigger, "/lander/resume", self.resume),
            (StepSimulation, "/lander/step", self.step),
            (RunUntil, "/lander/run_until", self.run_until),
            (Trigger, "/lander/deploy_parachute", self.deploy_parachute),
            (SetBool, "/lander/set_stabiliser", self.set_stabiliser),
            (Trigger, "/lander/subscribers", self.subscribers),
        )

    def _fail(self, name: str, response: Any, message: str) -> Any:
        self.node.reject(f"service.{name}", message)
        response.success, response.message = False, message
        return response

    def load_scene(self, request: Any, response: Any) -> Any:
        node = self.node
        try:
            sim = node.load(request.scene)
        except (SceneError, ValueError) as exc:
            return self._fail("load_scene", response, str(exc))
        node.sim = sim
        node.start_flight()
        response.success, response.message = True, f"loaded scene {sim.scene.name!r} (dt {sim.dt} s)"
        return response

    def reset(self, request: Any, response: Any) -> Any:
        node = self.node
        seed = int(request.seed) if request.use_seed else None
        try:
            node.sim.reset(seed)
        except ValueError as exc:
            return self._fail("reset", response, str(exc))
        node.apply_stabiliser(node.sim)  # the core's reset restores the scene's setting
        node.start_flight()
        response.success = True
        response.message = "reset to t = 0" + (f" with seed {seed}" if seed is not None else "")
        return response

    def pause(self, request: Any, response: Any) -> Any:
        # No state is published: the last one (at every tick boundary) already is the pause instant.
        # A diagnostics report goes out at once, so that whoever watches the state stream (the
        # launcher, the autopilot) knows the flight is paused before it misses a state.
        # The answer says what it was (`lander record --whole-flight` resumes only a running flight).
        node = self.node
        was = "paused" if node.gate.pause().paused else "running"
        if was == "running":
            node.pacer.stop(node.sim.t + node.steps_per_tick * node.sim.dt)  # behind when it stopped: counted
            node.report_now()
        response.success = True
        response.message = f"paused at t = {node.sim.t!r} s (was {was}){FLIGHT_SUFFIX}{node.flight}"
        return response

    def resume(self, request: Any, response: Any) -> Any:
        node = self.node
        refusal = node.gate.refusal(Event.RESUME)
        if refusal is not None:
            return self._fail("resume", response, refusal.message(node.sim.t))
        # Started paused: state 1, the controller's first question; held at pause_at: that instant's
        # state, now that inputs are in; awaiting an answer: the lockstep wait counts from here.
        pending = node.gate.resume(time.monotonic())
        node.check_subscribers(time.monotonic())  # who listens now gets this instant's odometry, pose, markers
        node.pacer.restart()
        node.publish_pending(pending)
        response.success, response.message = True, f"resumed at t = {node.sim.t!r} s"
        return response

    def subscribers(self, request: Any, response: Any) -> Any:
        """Subscriptions matched by each output's writer, and publishers matched by each input's
        reader as ``sub:TOPIC`` (lander_ros.flight_span.format_matched)."""
        response.success = True
        response.message = format_matched(self.node.matched())
        return response

    def step(self, request: Any, response: Any) -> Any:
        node = self.node
        refusal = node.gate.refusal(Event.STEP)
        if refusal is not None:
            response.sim_time = node.sim.t
            return self._fail("step", response, refusal.message(node.sim.t))
        if request.steps == 0:
            response.sim_time = node.sim.t
            return self._fail("step", response, "steps = 0: ask for at least one physics step")
        node.publish_pending(node.gate.advance())  # a pending state is the step's start
        node.advance(int(request.steps))
        response.success, response.sim_time = True, node.sim.t
        response.message = f"advanced {request.steps} steps of {node.sim.dt} s"
        return response

    def run_until(self, request: Any, response: Any) -> Any:
        node = self.node
        target = request.sim_time
        response.sim_time_reached = node.sim.t
        refusal = node.gate.refusal(Event.RUN_UNTIL)
        if refusal is not None:
            return self._fail("run_until", response, refusal.message(node.sim.t))
        if not math.isfinite(target) or target <= node.sim.t:
            return self._fail(
                "run_until", response, f"sim_time = {target!r} must be finite and later than now ({node.sim.t!r} s)"
            )
        # Whole steps, the last one reaching or passing the target (the 1e-9 absorbs float rounding of t/dt).
        n = max(1, math.ceil((target - node.sim.t) / node.sim.dt - 1e-9))
        node.publish_pending(node.gate.advance())  # a pending state is the start
        node.advance(n, stop_on_touchdown=True)
        response.success, response.sim_time_reached = True, node.sim.t
        response.message = f"reached t = {node.sim.t!r} s, phase {node.sim.phase_name}"
        return response

    def deploy_parachute(self, request: Any, response: Any) -> Any:
        node = self.node
        try:
            node.sim.deploy_parachute()
        except InputError as exc:
            return self._fail("deploy_parachute", response, str(exc))
        response.success, response.message = True, "parachute deploy requested"
        node.publish_core_events()
        return response

    def set_stabiliser(self, request: Any, response: Any) -> Any:
        self.node.sim.set_stabiliser(bool(request.data))
        response.success, response.message = True, f"stabiliser {'on' if request.data else 'off'}"
        return response
