"""What ``lander fly`` flies and how a flight ended: the plan, its timeline's actions, the result
and the exit codes (docs/flying.md, "Exit status"). Plain Python: no ROS here."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_CRASHED = 1
EXIT_ERROR = 2
EXIT_INCOMPLETE_BAG = 3
EXIT_INTERRUPTED = 130

SIM_NODE = "lander_sim"
AUTOPILOT_NODE = "autopilot"
ESTIMATOR_NODE = "lander_estimator"
#: The estimator node's outputs (lander_autopilot.ros.estimator_config.ESTIMATE_TOPICS).
ESTIMATE_TOPICS = ("/lander/estimate/odometry", "/lander/estimate/state")

ACTION_KINDS = ("demand_altitude", "wind", "controller", "throttle", "stabiliser", "parachute")


class LaunchError(ValueError):
    """A flight that cannot be launched as configured; the message names the setting."""


@dataclass(frozen=True)
class Action:
    """One timeline entry, applied at the first state with sim time >= ``t`` [s].

    ``kind`` / ``value``:

    * ``demand_altitude``: float, metres above the surface -> ``/lander/demand_altitude``
    * ``wind``: 3 floats, world frame m/s -> ``/lander/wind`` (frame ``mars``)
    * ``controller``: controller name (``value``) and ``params`` (mapping) ->
      ``/autopilot/switch_controller``
    * ``throttle``: list of throttles in [0, 1], held (re-sent with every state, so the sim's
      staleness limit never zeroes it) until ``until`` [s]; then zeros are sent once
    * ``stabiliser``: bool -> ``/lander/set_stabiliser``
    * ``parachute``: ignored value -> ``/lander/deploy_parachute``
    """

    t: float
    kind: str
    value: Any = None
    until: float | None = None
    params: dict[str, Any] = field(default_factory=dict)


@dataclass
class FlightPlan:
    """Everything a flight needs. ``controller``: ``None`` = the scene's autopilot, ``"none"`` = no autopilot."""

    scene: str
    controller: str | None = None
    controller_params: dict[str, Any] = field(default_factory=dict)
    duration: float | None = None
    speed: float = 1.0
    lockstep: bool | None = None
    params_file: Path | None = None
    sim_params: dict[str, Any] = field(default_factory=dict)
    autopilot_params: dict[str, Any] = field(default_factory=dict)
    record: Path | None = None
    storage: str = "mcap"
    topics: tuple[str, ...] | None = None
    compose: bool = False
    timeline: list[Action] = field(default_factory=list)
    end_on: tuple[str, ...] = ("landed", "crashed")
    meta: dict[str, str] = field(default_factory=dict)
    live: int | None = None  #: Foxglove port of a `lander live` started with the flight (docs/live.md); None: none
    #: ROS domain of the flight (``--domain``); None: the user's ROS_DOMAIN_ID, else one free on this
    #: machine (lander_tools.fly.domain). It changes no message of the flight.
    domain: int | None = None
    network: bool = False  #: discover over the network (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET), not this machine only
    #: Start the estimator node beside the sim (``--estimate``); the autopilot then flies on its estimate.
    estimate: bool = False

    def __post_init__(self) -> None:
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise LaunchError(f"duration = {self.duration!r}: must be a finite number of seconds > 0")
        if not (math.isfinite(self.speed) and self.speed >= 0):
            raise LaunchError(f"speed = {self.speed!r}: must be >= 0 (0 = as fast as possible)")
        for a in self.timeline:
            if a.kind not in ACTION_KINDS:
                raise LaunchError(f"timeline action {a.kind!r} is not known; choose one of {', '.join(ACTION_KINDS)}")
        bad = [e for e in self.end_on if e not in ("landed", "crashed")]
        if bad:
            raise LaunchError(f"end_on {bad}: allowed are landed, crashed")
        if self.estimate and self.compose:
            raise LaunchError("--estimate runs the estimator in its own process: it does not go with --compose")
        if self.params_file is not None and not Path(self.params_file).is_file():
            raise LaunchError(f"--params {self.params_file}: no such file")


@dataclass
class FlightResult:
    """How a flight ended."""

    outcome: str  #: landed | crashed | time-limit | interrupted | error
    exit_code: int
    sim_time: float
    states: int
    message: str = ""
    counts: dict[str, int] = field(default_factory=dict)
    bag: Path | None = None
    wall_time: float = 0.0
    #: The last state seen: altitude [m], climb rate [m/s], ground speed [m/s], fuel [kg], tilt [deg].
    final: dict[str, float] = field(default_factory=dict)
    #: Named values of the touchdown event (t_impact [s], descent_rate [m/s], ground_speed [m/s], ...).
    touchdown: dict[str, float] = field(default_factory=dict)
    #: The touchdown's classification against the scene's limits: safe, hard or crash ("" if none).
    touchdown_class: str = ""
    #: The bag's counts against what was published (close_and_check_bag).
    bag_check: str = ""
    #: Lockstep states the sim advanced past without the autopilot's answer (its FLIGHT_ENDED): with
    #: any, the flight is not the deterministic one (the autopilot was late, e.g. starved of CPU).
    lockstep_timeouts: int = 0
    #: The autopilot's controller and its gains in force at its last report (its /diagnostics), as
    #: one line (lander_autopilot.ros.loop_stats.format_gains); "" without an autopilot's report.
    controller: str = ""
    gains: str = ""


def pilot_mode(plan: FlightPlan, controller: str | None) -> bool:
    """True when the launcher itself answers the sim in lockstep (no autopilot; throttle
    overrides in the timeline, or ``lockstep`` asked for): timeline actions then happen
    exactly at the state they are due and the flight stops exactly at its time limit."""
    if controller is not None:
        return False
    return plan.lockstep is True or (plan.lockstep is None and any(a.kind == "throttle" for a in plan.timeline))
