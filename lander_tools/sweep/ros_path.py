"""Fly sweep cases through the ROS nodes (the ``lander fly`` path) and check them against core-only.

A case becomes a scene file (:mod:`lander_tools.sweep.case_scene`: dispersed initial state, true
vehicle, thruster failure, mean wind and seeded gusts, all inside the simulator) plus a timeline of
demand altitudes, flown by :mod:`lander_tools.fly` with both nodes in lockstep at full speed
and recorded; :func:`row_from_bag` reduces the bag to the very same :class:`Samples` and metrics
as the core-only loop, and :func:`through_ros` compares the two.

Settings that make the nodes fly the core-only loop's equations at its instants:

* sim ``publish_rate`` = the sweep's control rate (one state, one answer per control period);
* sim ``seed`` = the case's gust seed (the node's ``seed`` parameter reseeds the gusts at reset);
* sim ``lockstep_timeout`` long (a loaded machine must not let the sim step without the answer);
* autopilot ``scene`` = the *nominal* scene (the controller is designed on the nominal vehicle,
  as in core-only; the simulator flies the dispersed one).
"""
from __future__ import annotations

import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lander_tools.fly.plan import Action, FlightPlan
from lander_tools.sweep.case_scene import NotRepresentable, gust_seed, nominal_scene, write_case_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import control_period, demand_schedule, make_row
from lander_tools.sweep.metrics import HoverHold, Samples, altitude_and_tilt
from lander_tools.sweep.spec import CORE_ONLY_METRICS, NONDETERMINISTIC_METRICS, SweepSpec

__all__ = ["NotRepresentable", "RosCheck", "plan_for_case", "row_from_bag", "scene_file_for_case", "through_ros"]

#: Topics the check needs (fewer topics: a faster recorder and sim, see docs/flying.md).
TOPICS = ("/clock", "/lander/state", "/lander/events", "/lander/demand_altitude", "/lander/throttle", "/autopilot/status")
#: Wall seconds the sim waits for the autopilot's answer before stepping anyway (node default 1 s; kept
#: below the launcher's 30-s stall limit so a lost answer shows as a disagreement, not a stall).
LOCKSTEP_TIMEOUT = 10.0
#: Agreement tolerance, relative to max(1, |value|): both paths fly the same scene, the same
#: equations and the same control instants, and states cross the middleware as exact float64, so
#: they should agree to round-off; 1e-9 leaves room only for the nanosecond stamp of t.
RTOL = 1e-9
#: lander_interfaces/msg/FlightEvent.msg MODE_CHANGED; its detail ends "mode 'old' -> 'new'" (autopilot node).
EV_MODE_CHANGED = 11
_MODE_CHANGE = re.compile(r"-> '([^']*)'$")


def scene_file_for_case(spec: SweepSpec, index: int, folder: Path) -> Path:
    """Write flight ``index``'s scene as YAML into ``folder``; return its path."""
    case = draw_case(spec, index, nominal_scene(spec).vehicle.n_thrusters)
    return write_case_scene(spec, case, folder)


def plan_for_case(
    spec: SweepSpec, controller_index: int, index: int, folder: Path, record: Path | None,
    topics: tuple[str, ...] | None = None,
) -> FlightPlan:
    """A :class:`lander_tools.fly.plan.FlightPlan` flying case ``index`` in lockstep, as fast as possible."""
    if spec.controllers[controller_index].navigation != "truth":
        raise NotRepresentable(f"controller {spec.controllers[controller_index].label!r} flies on the estimate: "
                               "the through-ROS check flies the laws on the truth only (lander fly --estimate flies one)")
    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    scene_path = write_case_scene(spec, case, folder)
    _, period = control_period(spec, scene0.dt)
    before, after, t_change = demand_schedule(spec, scene0, case)
    timeline = [Action(0.0, "demand_altitude", before)]
    if after != before:
        # Exact in sim time: the launcher pauses the sim at t_change and waits until the autopilot
        # has the new demand before the state at t_change goes out (lander_tools.fly.timeline).
        timeline.append(Action(t_change, "demand_altitude", after))
    choice = spec.controllers[controller_index]
    seed = gust_seed(case) if case.wind_gust else (scene0.gust.seed if scene0.gust is not None else 0)
    return FlightPlan(
        scene=str(scene_path), controller=choice.name, controller_params=dict(choice.params),
        duration=spec.end.duration, speed=0.0, lockstep=True, record=record, topics=topics,
        sim_params={"publish_rate": 1.0 / period, "seed": seed, "lockstep_timeout": LOCKSTEP_TIMEOUT},
        autopilot_params={"scene": str(scene0.source)},
        timeline=timeline,
        meta={"sweep": spec.name, "seed": str(spec.seed), "flight": str(index), "controller": choice.label},
    )


def row_from_bag(spec: SweepSpec, controller_index: int, index: int, bag_path: Path) -> dict[str, Any]:
    """The flight's row computed from its bag with the core-only definitions (:mod:`.metrics`).

    States: the flight after the last reset, one per control instant (the resume republishes the
    t = 0 state: the last one per instant is kept), up to the first state no longer flying or the
    end. Saturation: ``/autopilot/status`` of the answers to those states. Touchdown speed: the
    LANDED/CRASHED event's ``hypot(descent_rate, ground_speed)``.
    """
    from lander_tools.analysis import EV_CRASHED, EV_LANDED, Flight

    EV_HARD_LANDING = 9  # lander_interfaces/msg/FlightEvent.msg HARD_LANDING
    from lander_tools.bagio import read_bag

    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    _, period = control_period(spec, scene0.dt)
    before, after, t_change = demand_schedule(spec, scene0, case)
    bag = read_bag(bag_path)
    f = Flight.from_bag(bag)
    n_ctrl = int(math.floor(spec.end.duration / period + 1e-9))
    # One state per control instant k: the last published for it (k from the stamp, to the ns).
    ks = np.rint(f.t / period).astype(int)
    last: dict[int, int] = {}
    for j, k in enumerate(ks):
        if 0 <= k <= n_ctrl:
            last[int(k)] = j
    ts, errs, tilts, rates, fuel, speeds = [], [], [], [], [], []
    terminal = "ok"
    # A hover-hold flight ends where the core-only loop stops it (the nodes fly on to the duration).
    hold = HoverHold(spec.end.hover_hold, spec.end.hover_band, spec.end.hover_speed) if spec.end.hover_hold > 0 else None
    for k in sorted(last):
        j = last[k]
        t = k * period
        h, tilt = altitude_and_tilt(f.r_W[j], f.q[j])
        ts.append(t)
        errs.append(h - (after if t >= t_change else before))
        tilts.append(tilt)
        rates.append(float(np.linalg.norm(f.omega_B[j])))
        speeds.append(float(np.linalg.norm(f.v_W[j])))
        fuel.append(float(f.fuel[j]))
        if f.phase[j] != 0:
            terminal = "crashed" if f.phase[j] == 2 else "landed"
            break
        if hold is not None and hold.update(t, errs[-1], speeds[-1]):
            break
    # Fuel at each mode's first answer: the MODE_CHANGED events, stamped with the state answered;
    # as the saturation below, only answers to instants before the last one kept (core-only asks none there).
    mode_fuel: dict[str, float] = {}
    for t_ev, kind, detail, _values in f.events:
        m = _MODE_CHANGE.search(detail) if kind == EV_MODE_CHANGED else None
        k_ev = int(round(t_ev / period))
        if m is not None and m.group(1) not in mode_fuel and k_ev in last and k_ev * period < ts[-1] - 1e-9:
            mode_fuel[m.group(1)] = float(f.fuel[last[k_ev]])
    t_last = ts[-1]
    # Controller updates happen at every instant flown except the last one recorded.
    sat = 0
    if f.status_t.size:
        st_k = np.rint(f.status_t / period).astype(int)
        by_k: dict[int, bool] = {}
        for k, s in zip(st_k, f.status_saturated):
            by_k[int(k)] = bool(s)
        if 0 not in by_k and last:
            # The answer to the very first state can go out before the recorder has discovered
            # /autopilot/status (seen in practice). At t = 0 the controller has just been reset,
            # so evaluating it on the recorded state gives exactly the flag it reported.
            from lander_autopilot.controllers.base import Demand
            from lander_sim.physics.state import StateView
            from lander_tools.sweep.flight import case_controller

            j = last[min(last)]
            st = StateView(0.0, f.r_W[j], f.v_W[j], f.q[j], f.euler[j], f.omega_B[j], float(f.fuel[j]))
            by_k[0] = bool(case_controller(spec, controller_index, scene0.vehicle).update(0.0, st, Demand(altitude=before)).saturated)
        sat = sum(1 for k, s in by_k.items() if s and k * period < t_last - 1e-9)
    touchdown = math.nan
    figures: dict[str, Any] = {}
    classes = {EV_LANDED: "safe", EV_HARD_LANDING: "hard", EV_CRASHED: "crash"}
    for t_ev, kind, _detail, values in f.events:
        # Events after the last state kept come from the sim running on while the nodes stop.
        if kind in classes and len(values) >= 3 and t_ev <= t_last + 1e-9:
            touchdown = math.hypot(values[1], values[2])
            # FlightEvent values: t_impact, descent_rate, ground_speed, tilt_deg, fuel_left.
            figures = dict(zip(("descent_rate", "ground_speed", "tilt_deg", "fuel_left"), (float(v) for v in values[1:])))
            figures["classification"] = classes[kind]
    samples = Samples(
        t=np.asarray(ts), altitude_error=np.asarray(errs), tilt=np.asarray(tilts), body_rate=np.asarray(rates),
        fuel_start=fuel[0], fuel_end=fuel[-1], saturated_updates=sat, period=period, touchdown_speed=touchdown,
        terminal=terminal, t_change=t_change, touchdown=figures, speed=np.asarray(speeds), mode_fuel=mode_fuel,
    )
    return make_row(spec, controller_index, index, case, samples)


@dataclass
class RosCheck:
    """The through-ROS sample: rows of both paths, disagreements, timing."""

    core_rows: list[dict[str, Any]]
    ros_rows: list[dict[str, Any]]
    mismatches: list[str] = field(default_factory=list)
    ros_wall: float = 0.0  # [s] wall time of the flights through ROS (start-up included)
    core_wall: float = 0.0  # [s] wall time of the same flights core-only, one process
    outcomes: list[str] = field(default_factory=list)

    @property
    def agree(self) -> bool:
        return not self.mismatches and bool(self.ros_rows)

    def summary(self) -> str:
        n = len(self.ros_rows)
        ros_fps = n / self.ros_wall if self.ros_wall > 0 and n else math.nan
        core_fps = n / self.core_wall if self.core_wall > 0 and n else math.nan
        head = (
            f"through ROS: {n} flight(s) in {self.ros_wall:.1f} s = {ros_fps:.3f} flights/s "
            f"(core-only, same flights, 1 process: {core_fps:.2f} flights/s, {core_fps / ros_fps:.0f}x faster); "
        )
        if self.agree:
            return head + f"metrics of {n}/{n} agree with core-only (relative tolerance {RTOL:g})"
        agreed = n - len({m.split(":")[0] for m in self.mismatches if "failed" not in m})
        return head + f"{agreed} agree; DISAGREEMENT:\n  " + "\n  ".join(self.mismatches)

    def as_dict(self) -> dict[str, Any]:
        return {"flights": len(self.ros_rows), "ros_wall_s": self.ros_wall, "core_wall_s": self.core_wall,
                "agree": self.agree, "rtol": RTOL, "mismatches": self.mismatches,
                "launcher": self.outcomes,
                "ros_rows": self.ros_rows}


def compare_rows(core: dict[str, Any], ros: dict[str, Any], metrics: tuple[str, ...], rtol: float = RTOL) -> list[str]:
    """Differences between a core-only and a through-ROS row (outcome, then each metric except the
    measured ones, :data:`~lander_tools.sweep.spec.NONDETERMINISTIC_METRICS`: compute time is not
    a property of the flight, and a bag has none; and the core-only ones, ``CORE_ONLY_METRICS``)."""
    where = f"flight {core['index']} ({core['controller']})"
    out = []
    if core["outcome"] != ros["outcome"]:
        out.append(f"{where}: outcome core-only {core['outcome']!r}, through ROS {ros['outcome']!r}")
    for m in metrics:
        if m in NONDETERMINISTIC_METRICS or m in CORE_ONLY_METRICS:
            continue
        a, b = float(core[m]), float(ros[m])
        if math.isnan(a) and math.isnan(b):
            continue
        if not abs(a - b) <= rtol * max(1.0, abs(a)):
            out.append(f"{where}: {m} core-only {a!r}, through ROS {b!r} (difference {b - a:.3g})")
    return out


def through_ros(spec: SweepSpec, n: int, folder: Path, core_rows: Sequence[Any] | None = None,
                out: Any = None, speed: float = 0.0) -> RosCheck:
    """Fly flights ``0..n-1`` (every controller) through the nodes, record each into ``folder``,
    compute their rows from the bags and compare with the core-only rows (flown here if not given)."""
    import io

    from lander_tools.fly.phases import fly  # the `lander fly` path: rclpy
    from lander_tools.fly.summary import summary
    from lander_tools.sweep.flight import fly_case

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    work = [(ci, i) for i in range(n) for ci in range(len(spec.controllers))]
    t0 = time.perf_counter()
    fresh = [fly_case(spec, ci, i).row for ci, i in work]
    core_wall = time.perf_counter() - t0
    if core_rows is not None:
        by = {(r["controller_index"], r["index"]): r for r in core_rows}
        fresh = [by.get((ci, i), row) for (ci, i), row in zip(work, fresh)]
    check = RosCheck(core_rows=fresh, ros_rows=[], core_wall=core_wall)
    for (ci, i), core in zip(work, fresh):
        log = io.StringIO()
        try:
            plan_for_case(spec, ci, i, folder, None, topics=TOPICS)
        except NotRepresentable as exc:  # e.g. a thruster cant: no scene key carries it yet
            check.mismatches.append(f"flight {i}: cannot be flown through ROS: {exc}")
            continue
        for attempt in range(2):
            bag = folder / f"flight-{i}-{spec.controllers[ci].label}" / f"attempt-{attempt + 1}"
            plan = plan_for_case(spec, ci, i, folder, bag, topics=TOPICS)
            plan.speed = speed
            w0 = time.perf_counter()
            result = fly(plan, out=log if out is None else out)
            check.ros_wall += time.perf_counter() - w0
            check.outcomes.append(f"flight {i}, attempt {attempt + 1}: " + summary(result))
            if result.outcome != "error":
                break  # an error is the nodes failing to start or talk (start-up race): one retry, reported
        if result.outcome not in ("time-limit", "landed", "crashed"):
            check.mismatches.append(f"flight {i}: the ROS flight failed: {summary(result)}\n{log.getvalue()[-2000:]}")
            continue
        ros = row_from_bag(spec, ci, i, bag)
        check.ros_rows.append(ros)
        check.mismatches += compare_rows(core, ros, spec.metrics)
    return check
