"""Fly ONE dispersed flight core-only (no ROS): Simulation + controller at the control rate.

The loop is the autopilot node's, without the middleware: every control period read the state,
ask the controller for throttles against the current demand, apply them (zeroing a failed
thruster), set the wind, and step the simulation one control period. Everything random comes from
the flight's :class:`~lander_tools.sweep.dispersion.FlightCase`, itself a function of
``(master seed, flight index)``, so a flight re-flown alone is bit-identical.

The controller is built on the **nominal** vehicle (what the designer believes) while the
simulation flies the **dispersed** one (mass, inertia and thrust errors): that is the robustness
question being asked.
"""
from __future__ import annotations

import math
import traceback
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.state import ATT, EULER, OMEGA_B, R_W, V_W
from lander_tools.sweep.dispersion import FlightCase, draw_case, gust_stream
from lander_tools.sweep.spec import SweepSpec


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


# Per-process caches: loading a scene and designing a controller (python-control) cost far more
# than a short flight, and are identical for every flight of a sweep.
_SCENES: dict[str, Any] = {}
_CONTROLLERS: dict[tuple[str, str, str], Any] = {}


def nominal_scene(spec: SweepSpec) -> Any:
    """The undispersed scene (cached per process)."""
    scene = _SCENES.get(spec.scene)
    if scene is None:
        from lander_sim.scenes import load_scene

        scene = _SCENES[spec.scene] = load_scene(spec.scene)
    return scene


def _controller(spec: SweepSpec, ci: int, vehicle: Any) -> Any:
    choice = spec.controllers[ci]
    key = (spec.scene, choice.name, repr(sorted(choice.params.items())))
    ctrl = _CONTROLLERS.get(key)
    if ctrl is None:
        from lander_autopilot.controllers import make_controller

        ctrl = _CONTROLLERS[key] = make_controller(choice.name, vehicle, **dict(choice.params))
    ctrl.reset()  # the contract: reset() forgets all internal state, so reuse equals a fresh build
    return ctrl


def apply_case(scene: Any, case: FlightCase) -> Any:
    """The scene as actually flown: dispersed vehicle and initial state (a new frozen Scene).

    * mass: ``dry_mass (1 + mass_error)``; inertia: ``gyration_sq`` or ``inertia_diag`` times
      ``(1 + inertia_error)``; each thruster's ``max_thrust`` times ``(1 + thrust_error_i)``.
    * attitude: ``q' = q x p`` with ``p`` the tilt about a horizontal *body* axis (eq 10: a
      right-multiplied quaternion rotates in the body frame under the world-to-body convention).
    * altitude offset along ``r_hat``; velocity offset in the world frame; body-rate offset.
    """
    v = scene.vehicle
    thrusters = tuple(
        replace(th, max_thrust=th.max_thrust * (1.0 + e)) for th, e in zip(v.thrusters, case.thrust_error)
    ) + tuple(v.thrusters[len(case.thrust_error):])
    kw: dict[str, Any] = {"dry_mass": v.dry_mass * (1.0 + case.mass_error), "thrusters": thrusters}
    f = 1.0 + case.inertia_error
    if v.gyration_sq is not None:
        kw["gyration_sq"] = tuple(k * f for k in v.gyration_sq)
    else:
        kw["inertia_diag"] = tuple(i * f for i in v.inertia_diag)
    vehicle = replace(v, **kw)

    y = np.array(scene.initial_state, dtype=float)
    r = y[R_W]
    rn = float(np.linalg.norm(r))
    if case.altitude_offset and rn > 0.0:
        y[R_W] = r + case.altitude_offset * r / rn
    y[V_W] += case.velocity_W
    y[OMEGA_B] += case.body_rate_B
    if case.tilt:
        p = rotation.axis_angle_to_quat(np.array([math.cos(case.tilt_azimuth), math.sin(case.tilt_azimuth), 0.0]), case.tilt)
        if scene.attitude == "quaternion":
            y[ATT] = rotation.quat_mult(y[ATT], p)
        else:
            y[EULER] = rotation.quat_to_euler(rotation.quat_mult(rotation.euler_to_quat(y[EULER]), p))
    return replace(scene, vehicle=vehicle, initial_state=y)


def base_demand_altitude(scene: Any) -> float:
    """Demand before any step [m]: the scene's ``autopilot.demand_altitude`` if set, else the
    autopilot's default :class:`Demand` altitude (scenario 7 starts 50 m above its 500 m hover)."""
    from lander_autopilot.controllers.base import Demand

    ap = scene.autopilot or {}
    if isinstance(ap.get("demand_altitude"), (int, float)) and not isinstance(ap.get("demand_altitude"), bool):
        return float(ap["demand_altitude"])
    return Demand().altitude


def wind_schedule(scene: Any, case: FlightCase, tau: float, period: float, n: int) -> np.ndarray | None:
    """World-frame wind [m/s] for each of ``n`` control periods, or None when there is none to set.

    Scene wind + the case's mean wind + gusts: a first-order Gauss-Markov process per world axis,
    discretised exactly over one period, ``g_{k+1} = a g_k + sigma sqrt(1 - a^2) w_k`` with
    ``a = exp(-period / tau)``, started in its stationary distribution (std ``sigma``).
    """
    base = np.asarray(scene.wind_W, dtype=float) + np.asarray(case.wind_mean_W)
    if not case.wind_gust:
        return None if not np.any(np.asarray(case.wind_mean_W)) else np.tile(base, (max(n, 1), 1))
    rng = gust_stream(case)
    a = math.exp(-period / tau)
    scale = case.wind_gust * math.sqrt(1.0 - a * a)
    out = np.empty((max(n, 1), 3))
    g = case.wind_gust * rng.standard_normal(3)
    for k in range(out.shape[0]):
        out[k] = base + g
        g = a * g + scale * rng.standard_normal(3)
    return out


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


def _phase_name(sim: Any) -> str:
    p = sim.phase
    return str(getattr(p, "name", getattr(p, "value", p))).upper()


def fly_case(spec: SweepSpec, controller_index: int, index: int, *, record: bool = False) -> FlightResult:
    """Fly flight ``index`` with controller ``controller_index``; metrics as in ``spec.METRICS``."""
    from lander_autopilot.controllers.base import Demand
    from lander_sim.simulation import Simulation

    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    scene = apply_case(scene0, case)
    ctrl = _controller(spec, controller_index, scene0.vehicle)
    sim = Simulation(scene)
    end = spec.end
    n_sub = _steps_per_control(spec, sim.dt)
    period = n_sub * sim.dt
    n_ctrl = int(math.floor(end.duration / period + 1e-9))

    h0 = base_demand_altitude(scene0)
    demand_before = Demand(altitude=max(0.0, h0))
    demand_after = Demand(altitude=max(0.0, h0 + case.demand_step)) if case.demand_step else demand_before
    t_change = end.demand_step_time if case.demand_step else 0.0

    winds = wind_schedule(scene, case, end.gust_time_constant, period, n_ctrl)

    fuel0 = float(sim.state().fuel)
    ts, errs, tilts, rates = [], [], [], []
    demands, alts, thr_log = [], [], []
    sat_steps = 0
    touchdown_speed = math.nan
    outcome = "ok"
    ez_B = np.array([0.0, 0.0, 1.0])
    failed = case.failed_thruster
    for k in range(n_ctrl + 1):
        st = sim.state()
        t = k * period
        r = st.r_W
        rn = math.sqrt(float(r @ r))
        if not math.isfinite(rn) or not np.all(np.isfinite(st.omega_B)):
            outcome = "diverged"
            break
        demand = demand_after if t >= t_change else demand_before
        h = rn - MARS_RADIUS
        up = rotation.body_to_world(st.q, ez_B)
        tilt = math.acos(max(-1.0, min(1.0, float(up @ r) / rn)))
        ts.append(t)
        errs.append(h - demand.altitude)
        tilts.append(tilt)
        rates.append(math.sqrt(float(st.omega_B @ st.omega_B)))
        phase = _phase_name(sim)
        if phase != "FLYING":
            outcome = "crashed" if phase == "CRASHED" else "landed"
            break
        if k == n_ctrl:
            break
        out = ctrl.update(t, st, demand)
        thr = out.throttles
        if failed >= 0 and t >= case.failure_time:
            thr = np.array(thr, dtype=float)
            thr[failed] = 0.0
        sat_steps += bool(out.saturated)
        if record:
            demands.append(demand.altitude)
            alts.append(h)
            thr_log.append(np.array(thr, dtype=float))
        if winds is not None:
            sim.set_wind(winds[k])
        sim.set_throttles(thr)
        v_before = st.v_W
        sim.step(n_sub)
        if _phase_name(sim) != "FLYING":
            touchdown_speed = _touchdown_speed(sim, v_before)

    e = np.asarray(errs)
    t_arr = np.asarray(ts)
    flown = float(t_arr[-1]) if t_arr.size else 0.0
    window = t_arr >= flown - end.hover_window
    hover = float(np.sqrt(np.mean(e[window] ** 2))) if e.size else math.nan
    settling = _settling_time(t_arr, e, t_change, end.settle_band)
    max_tilt = float(max(tilts)) if tilts else math.nan
    if outcome == "ok":
        if max_tilt > end.max_tilt:
            outcome = "tipped"
        elif not hover <= end.max_hover_error:
            outcome = "off-target"
    success = outcome == "ok" or (outcome == "landed" and end.allow_touchdown)
    fuel_end = float(sim.state().fuel) if outcome != "diverged" else math.nan
    metrics = {
        "touchdown_speed": touchdown_speed,
        "hover_error": hover,
        "final_altitude_error": float(e[-1]) if e.size else math.nan,
        "settling_time": settling,
        "fuel_used": fuel0 - fuel_end,
        "saturation_time": sat_steps * period,
        "max_tilt": max_tilt,
        "max_body_rate": float(max(rates)) if rates else math.nan,
        "flight_time": flown,
    }
    row: dict[str, Any] = {
        "index": index,
        "controller_index": controller_index,
        "controller": spec.controllers[controller_index].label,
        "outcome": outcome,
        "success": success,
        **case.parameters(),
        **{m: metrics[m] for m in spec.metrics},
        "error": "",
    }
    traj = None
    if record:
        m = len(thr_log)
        traj = Trajectory(
            t=t_arr[:m], altitude=np.asarray(alts), demand=np.asarray(demands), tilt=np.asarray(tilts[:m]),
            body_rate=np.asarray(rates[:m]), throttles=np.asarray(thr_log).reshape(m, -1),
        )
    return FlightResult(row, traj)


def _touchdown_speed(sim: Any, v_before: np.ndarray) -> float:
    """Impact speed [m/s] ``sqrt(descent_rate^2 + ground_speed^2)`` from the simulation's
    landed/crashed event (interpolated to the impact instant); if absent, the speed at the start
    of the control period in which contact happened."""
    for ev in sim.drain_events():
        vals = getattr(ev, "values", {}) or {}
        if "descent_rate" in vals and "ground_speed" in vals:
            return math.hypot(float(vals["descent_rate"]), float(vals["ground_speed"]))
    return float(np.linalg.norm(v_before))


def _settling_time(t: np.ndarray, e: np.ndarray, t_change: float, band: float) -> float:
    """Time from ``t_change`` until ``|e|`` stays within ``band`` to the end; NaN if it never does."""
    after = t >= t_change
    if not np.any(after):
        return math.nan
    ta, ea = t[after], np.abs(e[after])
    outside = np.nonzero(ea > band)[0]
    if outside.size == 0:
        return 0.0
    last = int(outside[-1])
    if last == ea.size - 1:
        return math.nan
    return float(ta[last + 1] - t_change)


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
    scene, unknown controller or parameter, a control rate that does not fit the scene's step."""
    scene = nominal_scene(spec)
    for ci in range(len(spec.controllers)):
        _controller(spec, ci, scene.vehicle)
    _steps_per_control(spec, scene.dt)
