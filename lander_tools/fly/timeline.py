"""The flight's timeline in sim time: the stops that put every action on the control grid, the
sim's ``pause_at`` armed at each, and an action applied while the sim stands there until it is in
force (docs/flying.md, "Timed actions")."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.parameter import Parameter

from lander_sim.ros.pacing import steps_per_tick
from lander_sim.scenes import load_scene
from lander_tools.fly.plan import Action, FlightPlan, LaunchError
from lander_tools.fly.supervisor import STARTUP_TIMEOUT, Supervisor, call

#: Wall seconds to wait for the autopilot to report a new demand in force.
CONFIRM_TIMEOUT = 10.0


@dataclass
class Stop:
    """Where a sim-time driven flight pauses: control instant ``index`` (t = index * period)."""

    index: int
    t: float
    actions: list[Action] = field(default_factory=list)


def plan_stops(timeline: list[Action], period: float, duration: float | None) -> list[Stop]:
    """The pauses that make ``timeline`` exact on the control grid ``t_k = k * period``.

    An action due at ``t`` belongs to the first instant ``t_k >= t``. The sim pauses having
    reached ``t_k`` but before publishing its state (``pause_at``), so sim-side actions (wind,
    stabiliser, parachute) act from the step leaving ``t_k`` and autopilot-side ones (demand,
    controller) from its answer to state k. Nothing is planned at or after the end (the first
    instant >= ``duration``, where the sim itself stops: its ``end_time``). Throttle overrides
    (sent with the states) and actions at instant 0 (applied before the flight starts) are not
    listed.
    """
    by_index: dict[int, Stop] = {}

    def stop(k: int) -> Stop:
        return by_index.setdefault(k, Stop(k, k * period))

    for a in timeline:
        k = max(0, math.ceil(a.t / period - 1e-9))
        if a.kind == "throttle" or k == 0:
            continue
        stop(k).actions.append(a)
    if duration is not None:
        k_end = math.ceil(duration / period - 1e-9)
        for k in [k for k in by_index if k >= k_end]:
            del by_index[k]  # nothing happens at or after the end: the flight stops there
    return [by_index[k] for k in sorted(by_index)]


def split_timeline(timeline: list[Action], period: float, duration: float | None) -> tuple[list[Stop], list[Action]]:
    """A sim-time driven flight's timeline (throttle overrides aside) on the control grid: the stops
    to come (:func:`plan_stops`) and the actions of instant 0, put in force before the first step."""
    timed = [a for a in timeline if a.kind != "throttle"]
    at_zero = [a for a in timed if math.ceil(a.t / period - 1e-9) <= 0]
    return plan_stops(timed, period, duration), at_zero


def control_period(executor: Any, sup: Supervisor, plan: FlightPlan) -> float:
    """The sim's control period [s]: ``steps_per_tick(dt, publish_rate) * dt``, read from the running node."""
    res = call(executor, sup.cli_sim_get, GetParameters.Request(names=["dt", "publish_rate"]), STARTUP_TIMEOUT,
               "sim parameters")
    dt, rate = res.values[0].double_value, res.values[1].double_value
    if dt <= 0.0:
        dt = load_scene(plan.scene).dt
    return float(steps_per_tick(dt, rate) * dt)


def arm(executor: Any, sup: Supervisor, t: float) -> None:
    """Set the sim's ``pause_at`` to ``t`` [s] (< 0: none): it pauses on reaching that instant."""
    req = SetParameters.Request(parameters=[Parameter("pause_at", value=float(t)).to_parameter_msg()])
    res = call(executor, sup.cli_sim_set, req, STARTUP_TIMEOUT, "pause_at")
    if not res.results[0].successful:
        raise LaunchError(f"the sim refused pause_at = {t}: {res.results[0].reason}")


def apply_now(executor: Any, sup: Supervisor, a: Action, at: float) -> None:
    """Apply ``a`` at instant ``at`` [s] while the sim is paused there, and wait until it is in force."""
    sup.apply(a, at)
    if a.kind == "demand_altitude":
        # Topic to the autopilot; its parameter says when the new demand is in force.
        deadline = time.monotonic() + CONFIRM_TIMEOUT
        while True:
            res = call(executor, sup.cli_ap_get, GetParameters.Request(names=["demand_altitude"]), CONFIRM_TIMEOUT,
                       "demand_altitude")
            v = res.values[0]
            if (v.double_value if v.type == ParameterType.PARAMETER_DOUBLE else float(v.integer_value)) == float(a.value):
                break
            if time.monotonic() > deadline:
                raise LaunchError(f"the autopilot did not take demand_altitude = {a.value} within {CONFIRM_TIMEOUT} s")
            executor.spin_once(timeout_sec=0.01)
    # Service calls (switch, stabiliser, parachute) were started by apply(): wait for their answers.
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while sup.futures:
        if time.monotonic() > deadline:
            raise LaunchError(f"no answer to {', '.join(n for n, _ in sup.futures)} within {STARTUP_TIMEOUT} s")
        executor.spin_once(timeout_sec=0.01)
        sup.check_futures()
