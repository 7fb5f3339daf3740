"""One flight being flown: its plan, its node processes, this process's own ROS side (the
supervisor and its executor), and what the flight must meet: the subscribers matched before it
starts and the messages its bag must hold."""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from lander_ros.flight_span import COUNTED_TOPICS, SIM_INPUT_TOPICS
from lander_tools.fly.plan import ESTIMATE_TOPICS, FlightPlan, LaunchError
from lander_tools.fly.processes import NodeProcess
from lander_tools.fly.supervisor import Supervisor, sensor_topics
from lander_tools.live.bridge import SUBSCRIBED_TOPICS as LIVE_TOPICS


class Interrupted(Exception):
    """A signal (SIGINT, SIGTERM) asked the flight to stop."""


class NodeDied(Exception):
    """A node process exited during the flight; the message names it, with its last lines."""


@dataclass
class LaunchedFlight:
    """One flight being flown: its plan, its node processes and this process's own ROS side."""

    plan: FlightPlan
    controller: str | None
    out: TextIO
    progress: Any
    env: dict[str, str] | None = None
    procs: dict[str, NodeProcess] = field(default_factory=dict)
    sup: Supervisor | None = None
    executor: Any = None  #: the SingleThreadedExecutor spinning the supervisor's node
    stop_reason: list[str] = field(default_factory=list)  #: signals received (SIGINT, SIGTERM)
    stopped: bool = False  #: stop_nodes() ran
    folder: Path | None = None  #: where the nodes' parameter files are written
    #: The flight's token, the sim's ``flight_id``: the launcher knows its own sim by it.
    flight_id: str = ""
    #: Where the flight runs on the middleware (ROS domain, discovery range), set by fly().
    place: Any = None
    #: Refused at start-up: another flight runs in the domain (no bag is kept).
    refused: bool = False
    #: (sim time [s], what) when another flight's nodes appeared in the domain mid-flight.
    joined: tuple[float, str] | None = None

    def spin(self, timeout: float = 0.05) -> None:
        """One executor pass; raises if a signal arrived or a node process died."""
        if self.stop_reason:
            raise Interrupted()
        for name, p in self.procs.items():
            if not p.alive():
                tail = "\n".join(p.lines[-5:])
                raise NodeDied(f"node process {name!r} exited with code {p.proc.returncode}" + (f":\n{tail}" if tail else ""))
        self.executor.spin_once(timeout_sec=timeout)

    def wait_for(self, done: Callable[[], bool], timeout: float, what: str) -> None:
        """Spin until ``done()``; LaunchError naming ``what`` after ``timeout`` wall seconds."""
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise LaunchError(f"{what} within {timeout} s")
            self.spin()


def flight_nodes(f: LaunchedFlight) -> dict[str, int]:
    """The flight's own nodes by name and how many of each (one more of any: another flight)."""
    nodes = {"lander_sim": 1, "lander_fly": 1}
    if f.controller is not None:
        nodes["autopilot"] = 1
    if f.plan.estimate:
        nodes["lander_estimator"] = 1
    return nodes


def strangers_in_graph(f: LaunchedFlight) -> str | None:
    """``"2 /lander_sim nodes"``-like words when the graph holds more of the flight's nodes than it
    has (another flight in the domain), else None."""
    assert f.sup is not None
    seen: dict[str, int] = {}
    for name, ns in f.sup.node.get_node_names_and_namespaces():
        if ns in ("/", ""):
            seen[name] = seen.get(name, 0) + 1
    over = [f"{seen[n]} /{n} nodes" for n, k in flight_nodes(f).items() if seen.get(n, 0) > k]
    return ", ".join(over) or None


def sim_outputs(f: LaunchedFlight) -> tuple[str, ...]:
    """The topics the flight's simulator publishes and counts: the sensors' too when its scene has
    any (lander_ros.flight_span.SENSOR_TOPICS)."""
    return COUNTED_TOPICS + sensor_topics(f.plan.scene)


def expected_subscribers(f: LaunchedFlight) -> dict[str, int]:
    """Per sim topic, the subscriptions its writer must have matched before the flight starts:
    this launcher's, the autopilot's and the recorder's (``sub:TOPIC``: publishers the sim's own
    subscription to TOPIC must have matched)."""
    sup = f.sup
    assert sup is not None
    need = {"/lander/state": 1, "/lander/events": 1, "sub:/lander/throttle": 1, "sub:/lander/wind": 1}
    if sup.timed:
        need["/clock"] = 1
    if f.controller is not None:
        need["sub:/lander/throttle"] += 1
    # the autopilot reads the states, or with --estimate the estimator does (its ticks) and every
    # sensor topic, and the autopilot reads the estimator's
    if f.controller is not None or f.plan.estimate:
        need["/lander/state"] += 1
    if f.plan.estimate:
        for t in sensor_topics(f.plan.scene):
            need[t] = need.get(t, 0) + 1
    if sup.recorder is not None:
        for t in sim_outputs(f):
            if sup.recorder.wanted(t):
                need[t] = need.get(t, 0) + 1
    if f.plan.live is not None:
        for t in LIVE_TOPICS:
            need[t] = need.get(t, 0) + 1
    return need


def expected_publishers(f: LaunchedFlight) -> dict[str, int]:
    """Per topic this process subscribes to (recorder, launcher), the publishers it must have
    matched: the sim's outputs, the autopilot's and this launcher's own."""
    pubs = {t: 1 for t in sim_outputs(f)}
    pubs.update({t: 1 for t in (*SIM_INPUT_TOPICS, "/lander/demand_altitude")})
    if f.controller is not None:
        pubs["/lander/throttle"] += 1
        pubs["/lander/events"] += 1
        pubs["/autopilot/status"] = 1
        pubs["/diagnostics"] += 1
    if f.plan.estimate:
        pubs.update({t: 1 for t in ESTIMATE_TOPICS})
    return pubs


def reference_counts(sup: Supervisor) -> dict[str, tuple[int, bool]]:
    """What the bag must hold per recorded topic: ``(count, exact)``.

    * the sim's own outputs: its FLIGHT_ENDED counts, exactly (``/lander/events`` too when the sim
      is its only publisher);
    * ``/lander/throttle``: in lockstep exactly one answer per state (the sim's ``/lander/state``
      count: the autopilot answers every lockstep state once, the end state too), or, if the sim
      advanced past some states without their answer (``FlightEnd.lockstep_timeouts``), at least one
      per state less those (an answer may still come after its timeout); otherwise at least
      what this launcher's own subscription received since the reset (nobody commands before the
      first state; that subscription can lose messages on a loaded machine, so it is no exact count);
    * ``/autopilot/status`` and, with an autopilot, ``/lander/events``: at least that (the
      autopilot may report before the flight, e.g. its start-up status, which the recorder may
      hold too);
    * ``/diagnostics`` with an autopilot: at least the sim's count plus the autopilot's reports this
      launcher received (both publish there; the bag cannot tell whose a message is by its count);
    * inputs this launcher published (wind, demand): at least what it sent (anyone may add more);
    * with the estimator (``--estimate``), each of its topics: exactly one estimate per state.
    """
    assert sup.recorder is not None
    ref: dict[str, tuple[int, bool]] = {}
    if sup.flight_end is not None:
        ref.update({t: (n, True) for t, n in sup.flight_end.counts.items()})
    if sup.lockstep and sup.controller is not None and sup.flight_end is not None:
        missed = sup.flight_end.lockstep_timeouts
        ref["/lander/throttle"] = (sup.flight_end.counts.get("/lander/state", 0) - missed, missed == 0)
    else:
        ref["/lander/throttle"] = (sup.received.get("/lander/throttle", 0), False)
    if sup.controller is not None:
        ref["/autopilot/status"] = (sup.received.get("/autopilot/status", 0), False)
        ref["/lander/events"] = (max(ref.get("/lander/events", (0, False))[0], sup.received.get("/lander/events", 0)),
                                 False)
        ref["/diagnostics"] = (ref.get("/diagnostics", (0, False))[0] + sup.received.get("/diagnostics", 0), False)
    for t in ("/lander/wind", "/lander/demand_altitude"):
        ref[t] = (sup.sent.get(t, 0), False)
    if sup.plan.estimate and sup.flight_end is not None:
        # the estimator answers every state of the flight with one estimate on each of its topics
        n = sup.flight_end.counts.get("/lander/state", 0)
        ref.update({t: (n, True) for t in ESTIMATE_TOPICS})
    return {t: v for t, v in ref.items() if sup.recorder.wanted(t)}


