"""Fly ONE dispersed flight core-only (no ROS): Simulation + controller at the control rate.

The loop is the autopilot node's, without the middleware: every control period read the state,
ask the controller for throttles against the current demand, apply them, and step the simulation
one control period. Everything else a case changes (initial state, true vehicle, thruster failure,
mean wind and gusts) is in the scene the flight flies (:mod:`lander_tools.sweep.case_scene`), so
the simulator node flies the very same scene through ROS. Everything random comes from the
flight's :class:`~lander_tools.sweep.dispersion.FlightCase`, itself a function of
``(master seed, flight index)``, so a flight re-flown alone is bit-identical.

The controller is built on the **nominal** vehicle (what the designer believes) while the
simulation flies the **dispersed** one (mass, inertia and thrust errors, failures): that is the
robustness question being asked.

A hover-hold sweep (``end.hover_hold``) stops a flight at the instant the hover has been held
(:class:`~lander_tools.sweep.metrics.HoverHold`). The CPU time of the controller's ``update`` calls
(``time.process_time``, the only thing timed) and the controller's ``diagnostics()`` after the
flight go into the row; they are measured, so they are the only numbers of a row that are not a
function of ``(seed, index)`` (:data:`~lander_tools.sweep.spec.NONDETERMINISTIC_METRICS`).
"""
from __future__ import annotations

import dataclasses
import math
import time
import traceback
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_tools.sweep.case_scene import clear_caches, flown_scene, nominal_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.metrics import HoverHold, Samples, altitude_and_tilt, evaluate, in_hover_band
from lander_tools.sweep.spec import SweepSpec

__all__ = [
    "FlightResult", "FlightSetupError", "Trajectory", "base_demand_altitude", "clear_caches", "control_period",
    "demand_schedule", "error_row", "fly_case", "fly_task", "nominal_scene", "preflight",
]


class FlightSetupError(ValueError):
    """The spec cannot be flown on this scene (e.g. control period not a whole number of steps)."""


@dataclass
class Trajectory:
    """Samples at the control instants (for the worst-flight plots); frames as named."""

    t: np.ndarray  # [s]
    altitude: np.ndarray  # [m]
    demand: np.ndarray  # [m]
    tilt: np.ndarray  # angle of body z from the local vertical [rad]
    body_rate: np.ndarray  # |omega_B| [rad/s]
    throttles: np.ndarray  # (n, N_thrusters) commanded, after any failure


@dataclass
class FlightResult:
    row: dict[str, Any]
    trajectory: Trajectory | None = None


# Per-process cache: designing a controller (python-control) costs far more than a short flight,
# and is identical for every flight of a sweep.
_CONTROLLERS: dict[tuple[str, str, str], Any] = {}


def case_controller(spec: SweepSpec, ci: int, vehicle: Any) -> Any:
    """The sweep's controller number ``ci`` for ``vehicle``, freshly reset (designed once per process
    and scene: designing costs far more than a short flight, and is the same for every flight)."""
    choice = spec.controllers[ci]
    key = (spec.scene, choice.name, repr(sorted(choice.params.items())))
    ctrl = _CONTROLLERS.get(key)
    if ctrl is None:
        from lander_autopilot.controllers import make_controller

        ctrl = _CONTROLLERS[key] = make_controller(choice.name, vehicle, **dict(choice.params))
    ctrl.reset()  # the contract: reset() forgets all internal state, so reuse equals a fresh build
    return ctrl


def navigator(spec: SweepSpec, ci: int, sim: Any) -> Any:
    """What controller ``ci`` flies on in ``sim``: None for the truth, or for ``navigation: estimate``
    the scene's sensors and the navigation filter riding along (:class:`~lander_autopilot.estimation.
    onboard.Onboard`, seeded by the flight's ``sensors.seed``), its covariance steps compiled (the
    estimator node's filter to rounding), modelling the nominal scene's sensors (the flown ones carry
    the case's ``sensor_*_error``). A scene without the sensors the filter needs is a
    :class:`FlightSetupError`."""
    if spec.controllers[ci].navigation != "estimate":
        return None
    from lander_autopilot.estimation.onboard import Onboard

    sensors = sim.scene.sensors
    if sensors is None or "imu" not in sensors.sections:
        raise FlightSetupError(f"controllers[{ci}].navigation: estimate: scene {spec.scene!r} has no sensors.imu "
                               "(fly on the estimate from a scene with sensors, e.g. landing-hover-sensors)")
    try:
        return Onboard(sim, sensors, compiled=True, model=nominal_scene(spec).sensors)
    except ValueError as exc:
        raise FlightSetupError(f"controllers[{ci}].navigation: estimate: {exc}") from exc


def base_demand_altitude(scene: Any) -> float:
    """Demand before any step [m]: the scene's ``autopilot.demand_altitude`` if set, else the
    autopilot's default :class:`Demand` altitude (scenario 7 starts 50 m above its 500 m hover)."""
    from lander_autopilot.controllers.base import Demand

    ap = scene.autopilot
    return Demand().altitude if ap is None or ap.demand_altitude is None else ap.demand_altitude


def demand_schedule(spec: SweepSpec, scene: Any, case: Any) -> tuple[float, float, float]:
    """``(demand before, demand after, step time)`` [m, m, s]: the scene's demand, stepped by the
    case's ``demand_step`` at ``end.demand_step_time`` (never below the ground)."""
    h0 = base_demand_altitude(scene)
    before = max(0.0, h0)
    if not case.demand_step:
        return before, before, 0.0
    return before, max(0.0, h0 + case.demand_step), spec.end.demand_step_time


def control_period(spec: SweepSpec, dt: float) -> tuple[int, float]:
    """Physics steps per control period and the period [s]."""
    n = _steps_per_control(spec, dt)
    return n, n * dt


def _steps_per_control(spec: SweepSpec, dt: float) -> int:
    if spec.control_rate is None:
        return 1
    period = 1.0 / spec.control_rate
    n = max(1, round(period / dt))
    if abs(n * dt - period) > 1e-9 * period:
        raise FlightSetupError(
            f"control_rate: {spec.control_rate} Hz gives a control period of {period} s, "
            f"not a whole number of the scene's {dt} s steps"
        )
    return n


def _finite(v: np.ndarray) -> bool:
    """Every component of ``v`` finite (``np.all(np.isfinite(v))`` without its dispatch)."""
    return all(map(math.isfinite, v.tolist()))


#: Phase -> its upper-case name, filled as phases are met (an enum member's name is a property look-up)
_PHASE_NAMES: dict[Any, str] = {}


def flight_phase(sim: Any) -> str:
    """The simulation's flight phase as an upper-case name (``FLYING``, ``LANDED``, ``CRASHED``, ...)."""
    p = sim.phase
    name = _PHASE_NAMES.get(p)
    if name is None:
        name = _PHASE_NAMES[p] = str(getattr(p, "name", getattr(p, "value", p))).upper()
    return name


def fly_case(
    spec: SweepSpec, controller_index: int, index: int, *, record: bool = False
) -> FlightResult:
    """Fly flight ``index`` with controller ``controller_index``; metrics as in ``spec.METRICS``."""
    from lander_autopilot.controllers.base import Demand
    from lander_sim.simulation import Simulation

    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    ctrl = case_controller(spec, controller_index, scene0.vehicle)
    sim = Simulation(flown_scene(spec, case))
    onboard = navigator(spec, controller_index, sim)
    n_sub, period = control_period(spec, sim.dt)
    n_ctrl = int(math.floor(spec.end.duration / period + 1e-9))
    h_before, h_after, t_change = demand_schedule(spec, scene0, case)
    demand_before, demand_after = Demand(altitude=h_before), Demand(altitude=h_after)

    fuel0 = float(sim.state().fuel)
    ts, errs, tilts, rates, speeds = [], [], [], [], []
    demands, alts, thr_log = [], [], []
    sat_steps = 0
    touchdown_speed = math.nan
    touchdown: dict[str, Any] = {}
    terminal = "ok"
    # Hover-hold sweeps stop once the hover has been held (metrics.HoverHold, the one definition).
    hold = HoverHold(spec.end.hover_hold, spec.end.hover_band, spec.end.hover_speed) if spec.end.hover_hold > 0 else None
    mode_fuel: dict[str, float] = {}
    handover: tuple[np.ndarray, np.ndarray, float, bool] | None = None  # r_W, v_W, fuel, chute open
    band_fuel = math.nan  # fuel at the first instant after the handover within the hover band and speed
    compute = 0.0
    for k in range(n_ctrl + 1):
        st = sim.state()
        t = k * period
        if not (_finite(st.r_W) and _finite(st.omega_B)):
            terminal = "diverged"
            break
        demand = demand_after if t >= t_change else demand_before
        h, tilt = altitude_and_tilt(st.r_W, st.q)
        ts.append(t)
        errs.append(h - (h_after if t >= t_change else h_before))
        tilts.append(tilt)
        rates.append(math.sqrt(float(st.omega_B @ st.omega_B)))
        speeds.append(math.sqrt(float(st.v_W @ st.v_W)))
        if (handover is not None and math.isnan(band_fuel) and hold is not None
                and in_hover_band(errs[-1], speeds[-1], spec.end.hover_band, spec.end.hover_speed)):
            band_fuel = float(st.fuel)
        phase = flight_phase(sim)
        if phase != "FLYING":
            terminal = "crashed" if phase == "CRASHED" else "landed"
            break
        if k == n_ctrl or (hold is not None and hold.update(t, errs[-1], speeds[-1])):
            break
        c0 = time.process_time()
        out = ctrl.update(t, st if onboard is None else onboard.state(), demand)
        compute += time.process_time() - c0
        if out.mode is not None and out.mode not in mode_fuel:
            mode_fuel[out.mode] = float(st.fuel)
            if out.mode == "powered-descent":
                handover = (st.r_W.copy(), st.v_W.copy(), float(st.fuel), chute_is_open(sim))
        act_on_requests(sim, out)
        sat_steps += bool(out.saturated)
        sim.set_throttles(out.throttles)
        v_before = st.v_W
        if onboard is None:
            sim.step(n_sub)
        else:
            onboard.step(n_sub)  # one step at a time, the sensors sampling each
        if record:
            demands.append(demand.altitude)
            alts.append(h)
            thr_log.append(sim.throttles)  # as applied over the period: a failed thruster shows 0
        if flight_phase(sim) != "FLYING":
            touchdown_speed, touchdown = touchdown_speed_of(sim, v_before)

    fuel_end = float(sim.state().fuel) if terminal != "diverged" else math.nan
    optimum = balanced = math.nan
    if handover is not None and not math.isnan(band_fuel):
        if {"powered_optimum", "fuel_ratio"} & set(spec.metrics):
            optimum = powered_optimum(sim, handover, h_after)
        if {"powered_optimum_balanced", "fuel_ratio_balanced"} & set(spec.metrics):
            balanced = powered_optimum(sim, handover, h_after, balanced=True)
    samples = Samples(
        t=np.asarray(ts), altitude_error=np.asarray(errs), tilt=np.asarray(tilts), body_rate=np.asarray(rates),
        fuel_start=fuel0, fuel_end=fuel_end, saturated_updates=sat_steps, period=period,
        touchdown_speed=touchdown_speed, terminal=terminal, t_change=t_change, touchdown=touchdown,
        speed=np.asarray(speeds), mode_fuel=mode_fuel, compute_time=compute, diagnostics=dict(ctrl.diagnostics()),
        powered_optimum=optimum, powered_optimum_balanced=balanced, band_fuel=band_fuel,
    )
    row = make_row(spec, controller_index, index, case, samples)
    traj = None
    if record:
        m = len(thr_log)
        traj = Trajectory(
            t=samples.t[:m], altitude=np.asarray(alts), demand=np.asarray(demands), tilt=samples.tilt[:m],
            body_rate=samples.body_rate[:m], throttles=np.asarray(thr_log).reshape(m, -1),
        )
    return FlightResult(row, traj)


def flown_periods(spec: SweepSpec, controller_index: int, index: int,
                  **params: Any) -> Iterator[tuple[float, Any, Any, Any]]:
    """Flight ``index`` with controller ``controller_index`` as :func:`fly_case` flies it (the same
    scene, case, demand schedule, control instants ``k * period`` and requests), a control period at
    a time, for replays that look inside the law: yields ``(t, the state the law was given, the law
    after its update, the simulation after the period)``. ``params`` go over the spec's controller
    parameters. Ends at ``end.duration`` or once the lander is down."""
    from lander_autopilot.controllers import make_controller
    from lander_autopilot.controllers.base import Demand
    from lander_sim.simulation import Simulation

    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    choice = spec.controllers[controller_index]
    ctrl = make_controller(choice.name, scene0.vehicle, **{**dict(choice.params), **params})
    sim = Simulation(flown_scene(spec, case))
    n_sub, period = control_period(spec, sim.dt)
    h_before, h_after, t_change = demand_schedule(spec, scene0, case)
    demand_before, demand_after = Demand(altitude=h_before), Demand(altitude=h_after)
    for k in range(int(math.floor(spec.end.duration / period + 1e-9))):
        t = k * period
        st = sim.state()
        out = ctrl.update(t, st, demand_after if t >= t_change else demand_before)
        act_on_requests(sim, out)
        sim.set_throttles(out.throttles)
        sim.step(n_sub)
        yield t, st, ctrl, sim
        if flight_phase(sim) != "FLYING":
            return


def chute_is_open(sim: Any) -> bool:
    """Whether the simulation's parachute is deployed (False for a scene without one)."""
    chute = getattr(sim, "parachute", None)
    return chute is not None and getattr(chute.status, "name", "") == "DEPLOYED"


def powered_optimum(sim: Any, handover: tuple[np.ndarray, np.ndarray, float, bool], demand_altitude: float,
                    balanced: bool = False, end_band: float = 0.0, end_speed: float = 0.0) -> float:
    """The fuel yardstick of a flight (docs/deorbit.md, "The fuel yardstick"): the minimum fuel [kg]
    from its handover state (world frame ``r_W``, ``v_W``, fuel, chute open) to rest at ``demand_altitude`` [m], with the flown vehicle (its
    thrust, mass and cant dispersions), the flown atmosphere's surface density and the scene's mean
    wind (the gusts are not modelled: they average out over the burn). 30 nodes, final time to 1e-3 s (the fuel agrees with 60 nodes to ~1e-6 from the
    common handover case, bench/deorbit_fuel.py uses 60). NaN when the convex problem is infeasible.
    ``balanced``: the thrust bound the flown thrusters give with no torque (``handover_problem``'s).
    ``end_band`` [m], ``end_speed`` [m/s]: the end anywhere within that band of the demand under that
    speed instead of at rest at it (``DescentProblem``'s)."""
    from lander_autopilot.guidance.fuel_optimal import GuidanceError, solve

    problem = yardstick_problem(sim, handover, demand_altitude, balanced, end_band, end_speed)
    try:
        return float(solve(problem, steps=30, t_tol=1e-3).fuel)
    except GuidanceError:
        return math.nan


def yardstick_problem(sim: Any, handover: tuple[np.ndarray, np.ndarray, float, bool], demand_altitude: float,
                      balanced: bool = False, end_band: float = 0.0, end_speed: float = 0.0) -> Any:
    """The :class:`~lander_autopilot.guidance.fuel_optimal.DescentProblem` :func:`powered_optimum`
    solves (same arguments): the flown vehicle, atmosphere and mean wind at the handover state."""
    from lander_autopilot.controllers.deorbit_mpc import handover_problem

    r_W, v_W, fuel, chute = handover
    atmosphere = sim.dynamics.atmosphere
    kwargs: dict[str, Any] = {"wind_W": np.asarray(sim.scene.wind_W, float)}
    if atmosphere is not None:
        kwargs["surface_density"] = float(atmosphere.surface_density)
    problem, _frame = handover_problem(sim.scene.vehicle, r_W, v_W, fuel, demand_altitude, chute_open=chute,
                                       balanced=balanced, **kwargs)
    if end_band or end_speed:
        problem = dataclasses.replace(problem, end_band=end_band, end_speed=end_speed)
    return problem


def make_row(spec: SweepSpec, controller_index: int, index: int, case: Any, samples: Samples) -> dict[str, Any]:
    """The table row of one flight: identity, outcome, the case's parameters and the kept metrics."""
    outcome, success, metrics = evaluate(samples, spec.end)
    return {
        "index": index,
        "controller_index": controller_index,
        "controller": spec.controllers[controller_index].label,
        "outcome": outcome,
        "success": success,
        **case.parameters(),
        **{m: metrics[m] for m in spec.metrics},
        "error": "",
    }


def touchdown_speed_of(sim: Any, v_before: np.ndarray) -> tuple[float, dict[str, Any]]:
    """Impact speed [m/s] ``sqrt(descent_rate^2 + ground_speed^2)`` from the simulation's
    landed/hard-landing/crashed event (interpolated to the impact instant), with the event's
    touchdown figures and classification; if absent, the speed at the start of the control period
    in which contact happened and no figures."""
    classes = {"landed": "safe", "hard_landing": "hard", "crashed": "crash"}
    for ev in sim.drain_events():
        vals = getattr(ev, "values", {}) or {}
        if "descent_rate" in vals and "ground_speed" in vals:
            td: dict[str, Any] = {k: float(vals[k]) for k in ("descent_rate", "ground_speed", "tilt_deg", "fuel_left")
                                  if k in vals}
            td["classification"] = classes.get(getattr(ev.kind, "value", str(ev.kind)), "crash")
            return math.hypot(float(vals["descent_rate"]), float(vals["ground_speed"])), td
    return float(np.linalg.norm(v_before)), {}


def act_on_requests(sim: Any, out: Any) -> None:
    """Do what the autopilot node does with a law's requests (``ControlOutput.requests``): deploy
    the parachute (refused quietly if the scene has none: the node's service call fails the same
    way); a ``landing_unreachable`` report changes nothing in the flight."""
    if not getattr(out, "requests", ()):
        return
    from lander_autopilot.controllers.base import REQUEST_DEPLOY_PARACHUTE
    from lander_sim.errors import InputError

    for req in getattr(out, "requests", ()):
        if req.kind == REQUEST_DEPLOY_PARACHUTE:
            try:
                sim.deploy_parachute()
            except InputError:
                pass


def error_row(spec: SweepSpec, controller_index: int, index: int, exc: BaseException) -> dict[str, Any]:
    """A row for a flight that raised: outcome ``error``, metrics NaN, the message kept."""
    try:
        params = draw_case(spec, index, nominal_scene(spec).vehicle.n_thrusters).parameters()
    except Exception:  # noqa: BLE001 - the scene itself may be what failed
        params = {}
    return {
        "index": index,
        "controller_index": controller_index,
        "controller": spec.controllers[controller_index].label,
        "outcome": "error",
        "success": False,
        **params,
        **{m: math.nan for m in spec.metrics},
        "error": "".join(traceback.format_exception_only(type(exc), exc)).strip(),
    }


def fly_task(spec: SweepSpec, controller_index: int, index: int) -> dict[str, Any]:
    """The runner's unit of work: one flight's row; an exception becomes an ``error`` row, so one
    bad flight never stops a sweep of thousands (setup errors are raised by the caller's dry run)."""
    try:
        return fly_case(spec, controller_index, index).row
    except FlightSetupError:
        raise
    except Exception as exc:  # noqa: BLE001 - recorded in the row, counted as a failure
        return error_row(spec, controller_index, index, exc)


def preflight(spec: SweepSpec) -> None:
    """Fail fast, once, in the calling process on what would make *every* flight fail: unknown
    scene, a scene that cannot carry a case, unknown controller or parameter, a control rate that
    does not fit the scene's step."""
    scene = nominal_scene(spec)
    flown_scene(spec, draw_case(spec, 0, scene.vehicle.n_thrusters))
    for ci in range(len(spec.controllers)):
        case_controller(spec, ci, scene.vehicle)
        from lander_sim.simulation import Simulation

        if spec.controllers[ci].navigation == "estimate":
            navigator(spec, ci, Simulation(scene))
    _steps_per_control(spec, scene.dt)
