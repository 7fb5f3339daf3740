"""The batched core of a sweep: many dispersed flights advanced together by one compiled loop.

Used whenever every controller of the spec has a compiled form
(:func:`~lander_autopilot.controllers.compiled.compiled_form`) and the scene fits the compiled
fast path (:func:`lander_sim.fast.unsupported_reason`, no stabiliser); :func:`unsupported_reason`
says why not otherwise, and the sweep then flies per flight (:func:`~.flight.fly_task`).

Each flight is set up exactly as the per-flight path sets it up: its case
(:func:`~.dispersion.draw_case`), its scene (:func:`~.case_scene.flown_scene`) and a
:class:`~lander_sim.simulation.Simulation` of it, from which the packed model parameters, the
initial state, the scheduled failures, the ground and the gust process are read; the gust process's
own generator then draws the normals the flight will use, in the order the Simulation would draw
them (three per physics step), so the gusts are the same numbers. The compiled loop
(:func:`~.batched_kernel.fly_flights`) returns the samples of :class:`~.metrics.Samples`, and the row
is made by the same :func:`~.flight.make_row`. A touchdown is handed back to the flight's
Simulation (its own interpolation and classification); a flight the loop cannot finish (throttles
the Simulation would refuse) is re-flown per flight, so its error row is the per-flight one.

**Fast set-up.** Building a scene and a Simulation per flight only to read those values back
costs about four times the compiled flight itself, so when the nominal scene allows it
(:class:`SetupTemplate`: a preset vehicle with ``gyration_sq``, quaternions, no failures or gusts of its
own, no dispersion keys in its file) the values are derived from the nominal scene's Simulation,
built once per process, by the very operations the scene loader and the Simulation apply (dry
mass and inertia times their scales, thrust ``-d_i (T_i s_i)`` per thruster and its torque
``p_i x F_i``, the initial state re-normalised as the loader does, failure steps, the gust
process of the case's own seed); ``test_batched.py`` holds them bit-identical to the Simulation's.
The flight's Simulation is then built only if it is needed (a touchdown to hand back).

**On the estimate** (a law with ``navigation: estimate``): each flight's sensors and filter are set
up as :func:`~.flight.navigator` sets them up (:func:`pack_navigation`: the flight's own sensors
switched on, their generators drawing the normals the flight's samples take, the filter started from
the nominal scene's model), and fly inside the compiled loop; flights on the estimate go through it
:data:`NAV_CHUNK` at a time (the normals are about 150 B a step a flight).

Memory is bounded by flying in chunks of ``chunk`` flights.
"""
from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_tools.sweep import batched_kernel as bk
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import FlightCase, draw_case
from lander_tools.sweep.flight import (
    case_controller,
    control_period,
    demand_schedule,
    fly_task,
    make_row,
    touchdown_speed_of,
)
from lander_tools.sweep.metrics import Samples, altitude_and_tilt
from lander_tools.sweep.spec import SweepSpec

__all__ = ["DEFAULT_CHUNK", "NAV_CHUNK", "chunks", "fly_chunk", "fly_compiled", "laws_of", "navigation_unsupported",
           "navigation_row", "pack_navigation", "path_detail", "stack_navigation",
           "unsupported_reason"]

#: Flights per chunk: about 50 kB each for a 60 s flight at 10 Hz (samples, gust normals, Simulation).
DEFAULT_CHUNK = 1000
#: Flights per compiled call on the estimate: each carries its sensors' normals (~150 B a step).
NAV_CHUNK = 50


def laws_of(spec: SweepSpec) -> list[Any] | None:
    """The compiled form of each controller of the spec (built on the nominal vehicle), or None."""
    from lander_autopilot.controllers.compiled import compiled_form

    vehicle = nominal_scene(spec).vehicle
    laws = [compiled_form(case_controller(spec, ci, vehicle)) for ci in range(len(spec.controllers))]
    return None if any(law is None for law in laws) else laws


def unsupported_reason(spec: SweepSpec) -> str | None:
    """Why the spec cannot fly on the batched core (None if it can)."""
    from lander_autopilot.controllers.compiled import compiled_form
    from lander_sim import fast

    if not bk.HAVE_NUMBA:
        return "numba is not installed"
    scene = nominal_scene(spec)
    why = fast.unsupported_reason(scene)
    if why is not None:
        return f"scene {scene.name!r}: {why}"
    if scene.stabiliser:
        return f"scene {scene.name!r} has the stabiliser on (the compiled loop has none)"
    if spec.end.hover_hold > 0:
        return "end.hover_hold: the compiled loop has no hover-hold stop"
    for ci, choice in enumerate(spec.controllers):
        if compiled_form(case_controller(spec, ci, scene.vehicle)) is None:
            return f"controller {choice.label!r} has no compiled form"
        if choice.navigation == "estimate":
            why = navigation_unsupported(scene)
            if why is not None:
                return f"controller {choice.label!r} flies on the estimate: {why}"
    return None


def navigation_unsupported(scene: Any) -> str | None:
    """Why the compiled loop cannot fly the sensors and filter of ``scene`` (None if it can): it
    needs what :class:`~lander_autopilot.estimation.onboard.Onboard` needs (an IMU sampling every
    step, inverse-square gravity; the per-flight path reports their absence as the error it is)
    and a quaternion scene (the sensors read the attitude as a quaternion)."""
    sensors = scene.sensors
    if sensors is None or "imu" not in sensors.sections:
        return f"scene {scene.name!r} has no sensors.imu"
    g = scene.models.get("gravity")
    if g is None or g.kind != "inverse-square":
        return f"scene {scene.name!r}: the filter needs inverse-square gravity"
    if float(sensors.sections["imu"]["rate"]) * scene.dt < 1.0 - 1e-9:
        return f"scene {scene.name!r}: sensors.imu.rate must sample every step"
    if scene.attitude != "quaternion":
        return f"scene {scene.name!r} is not a quaternion scene"
    return None


def path_detail(spec: SweepSpec) -> str:
    """What the batched path flies besides the law: the sensors and filter when a law flies on the estimate."""
    if any(c.navigation == "estimate" for c in spec.controllers):
        return "sensors and navigation filter compiled in the loop"
    return ""


@dataclass
class FlightSetup:
    """One flight's set-up (the per-flight path's objects, kept for touchdown and fallback).

    ``sim`` is the flight's Simulation; with the fast set-up it is None until needed
    (:meth:`simulation`) and ``values`` holds what :func:`_pack` would read from it."""

    index: int
    case: FlightCase
    sim: Any
    demand: tuple[float, float, float]  # before [m], after [m], step time [s]
    spec: Any = None
    values: dict[str, Any] | None = None
    scene: Any = None

    def flown_scene(self) -> Any:
        """The flight's scene (:func:`~.case_scene.flown_scene`, built once)."""
        if self.scene is None:
            self.scene = self.sim.scene if self.sim is not None else flown_scene(self.spec, self.case)
        return self.scene

    def simulation(self) -> Any:
        """The flight's Simulation (built now from its scene if the fast set-up skipped it)."""
        if self.sim is None:
            from lander_sim.simulation import Simulation

            self.sim = Simulation(self.flown_scene())
        return self.sim


def setup_flight(spec: SweepSpec, index: int, n_thrusters: int) -> FlightSetup:
    """Flight ``index`` set up as the per-flight path does: its case drawn, its scene and Simulation built."""
    from lander_sim.simulation import Simulation

    case = draw_case(spec, index, n_thrusters)
    sim = Simulation(flown_scene(spec, case))
    return FlightSetup(index, case, sim, demand_schedule(spec, nominal_scene(spec), case))


#: Vehicle keys of a nominal scene file the fast set-up reproduces (a dispersion key would be overwritten).
_PLAIN_VEHICLE_KEYS = {"preset", "thrusters", "disabled", "size"}
#: The case fields the fast set-up writes into a flight; a case with others (a new dispersion) is
#: set up by building its scene and Simulation until :meth:`SetupTemplate.values` learns them.
_KNOWN_CASE_FIELDS = {"index", "seed", "tilt", "tilt_azimuth", "body_rate_B", "altitude_offset", "velocity_W",
                      "wind_mean_W", "wind_gust", "demand_step", "mass_error", "inertia_error", "thrust_error",
                      "failed_thruster", "failure_time", "orbit_altitude", "orbit_phase", "density_error",
                      "thruster_cant", "thruster_cant_azimuth",
                      "sensor_noise_error", "sensor_bias_error"}  # the sensors observe: no part of the physics


class SetupTemplate:
    """What every flight of a sweep shares, from the nominal scene and its Simulation (built once
    per process), and the arithmetic that makes one flight's packed values from its case.

    :attr:`why_not` is None when the fast set-up reproduces the per-flight set-up exactly for this
    scene, else why not (then every flight is set up by building its Simulation)."""

    def __init__(self, spec: SweepSpec) -> None:
        from lander_sim.simulation import Simulation
        from lander_tools.sweep.case_scene import scene_data

        scene = self.scene = nominal_scene(spec)
        self.why_not: str | None = None
        sim = Simulation(scene)
        fk = sim.fast_kernel
        v = scene.vehicle
        try:
            raw_vehicle = set(scene_data(spec)["vehicle"])
        except Exception as exc:  # noqa: BLE001 - the per-flight set-up reports it
            raw_vehicle, self.why_not = set(), f"scene not representable: {exc}"
        if fk is None:
            self.why_not = "no compiled kernel"
        elif scene.attitude != "quaternion" or v.gyration_sq is None:
            self.why_not = "not a quaternion scene with a gyration-radius vehicle"
        elif scene.thruster_failures or scene.gust is not None:
            self.why_not = "the nominal scene has failures or gusts of its own"
        elif not raw_vehicle <= _PLAIN_VEHICLE_KEYS:
            self.why_not = f"the nominal scene's vehicle has keys {sorted(raw_vehicle - _PLAIN_VEHICLE_KEYS)}"
        else:
            import dataclasses

            extra = {f.name for f in dataclasses.fields(FlightCase)} - _KNOWN_CASE_FIELDS
            if extra:
                self.why_not = f"the case has fields the fast set-up does not write: {sorted(extra)}"
        if self.why_not is not None or fk is None:  # no kernel sets why_not
            return
        self.dt = sim.dt
        self.params = fk.params.copy()
        self.burn = np.array(fk.burn, dtype=float)
        self.dry = v.dry_mass
        self.k2 = tuple(v.gyration_sq)
        th = v.thrusters
        self.max_thrust = [t.max_thrust for t in th]
        # Thrusters.__post_init__'s operands: -d_i, enabled mask, positions.
        self.directions = [t.direction_B for t in th]
        self.neg_d = np.array([-np.asarray(d, float) for d in self.directions]).reshape(-1, 3)
        self.density = None if scene.models.get("atmosphere") is None else scene.models.get("atmosphere").surface_density
        self.on = np.array([1.0 if t.enabled else 0.0 for t in th]).reshape(-1, 1)
        self.pos = np.array([np.asarray(t.position_B, float) for t in th]).reshape(-1, 3)
        self.stop = sim.ground.contact_radius if sim.ground is not None else 0.0
        self.has_ground = sim.ground is not None
        self._demands: dict[float, np.ndarray] = {}

    def demand(self, altitude: float) -> np.ndarray:
        """``demand_array`` of ``Demand(altitude=altitude)`` (cached: a function of the number alone)."""
        d = self._demands.get(altitude)
        if d is None:
            from lander_autopilot.controllers.base import Demand
            from lander_autopilot.controllers.compiled import demand_array

            dm = Demand(altitude=altitude)
            d = self._demands[altitude] = demand_array(dm.altitude, dm.attitude, dm.omega_B)
        return d

    def values(self, spec: SweepSpec, case: FlightCase) -> dict[str, Any]:
        """The flight's packed values, as :func:`_pack` reads them from its Simulation: each is
        computed by the operation the loader / Simulation applies (see the module docstring)."""
        from lander_sim.fast import lander_kernel as lk
        from lander_sim.physics import rotation
        from lander_sim.physics.state import ATT
        from lander_sim.physics.wind import GustConfig, GustProcess
        from lander_tools.sweep.case_scene import (
            NotRepresentable,
            canted_directions,
            dispersed_initial_state,
            gust_seed,
        )

        # Initial state: case_scene_data writes it out, the loader re-normalises the quaternion.
        y = dispersed_initial_state(self.scene, case)
        y[ATT] = rotation.quat_normalise(y[ATT].copy())
        # Vehicle: vehicles.disperse (a scale of 1.0, or none, leaves each number as it is).
        mass_s = 1.0 + case.mass_error if case.mass_error else 1.0
        inertia_s = 1.0 + case.inertia_error if case.inertia_error else 1.0
        p = self.params.copy()
        p[lk.P_DRY] = self.dry * mass_s
        p[lk.P_K1], p[lk.P_K2], p[lk.P_K3] = (k * inertia_s for k in self.k2)
        if case.density_error:  # case_scene_data: rho0 (1 + e)
            if self.density is None:
                raise NotRepresentable(f"dispersions.density_error: scene {self.scene.name!r} has no atmosphere")
            p[lk.P_RHO0] = float(self.density * (1.0 + case.density_error))
        if any(case.thrust_error):
            tmax = np.array([t * (1.0 + e) for t, e in zip(self.max_thrust, case.thrust_error)])
        else:
            tmax = np.array(self.max_thrust, dtype=float)
        neg_d = self.neg_d
        if case.thruster_cant:  # flown_scene: the directions tilted, then Thrusters' -d_i
            dirs = canted_directions(self.directions, case.thruster_cant, case.thruster_cant_azimuth)
            neg_d = np.array([-np.asarray(d, float) for d in dirs]).reshape(-1, 3)
        force = neg_d * tmax.reshape(-1, 1) * self.on  # Thrusters: -d_i T_max, times enabled
        torque = np.cross(self.pos, force).reshape(-1, 3)
        out: dict[str, Any] = {
            "y0": y, "kparams": p, "force": force, "torque": torque, "burn": self.burn,
            "mean_wind": np.array([float(a + b) for a, b in zip(self.scene.wind_W, case.wind_mean_W)]),
            "gust": None, "failures": [],
        }
        if case.failed_thruster >= 0:  # Simulation._schedule_failures
            out["failures"] = [(max(0, math.ceil(float(case.failure_time) / self.dt - 1e-9)), case.failed_thruster)]
        if case.wind_gust:
            out["gust"] = GustProcess(GustConfig(sigma=float(case.wind_gust), tau=float(spec.end.gust_time_constant),
                                                 seed=gust_seed(case)), self.dt)
        return out


_TEMPLATES: dict[str, SetupTemplate] = {}


def template_of(spec: SweepSpec) -> SetupTemplate:
    """The spec's :class:`SetupTemplate` (per process, rebuilt if the nominal scene was reloaded)."""
    scene = nominal_scene(spec)
    tpl = _TEMPLATES.get(spec.scene)
    if tpl is None or tpl.scene is not scene:
        tpl = _TEMPLATES[spec.scene] = SetupTemplate(spec)
    return tpl


def setup_flight_fast(spec: SweepSpec, index: int, tpl: SetupTemplate) -> FlightSetup:
    """Flight ``index`` set up without building its scene or Simulation (see :class:`SetupTemplate`)."""
    case = draw_case(spec, index, len(tpl.max_thrust))
    return FlightSetup(index, case, None, demand_schedule(spec, tpl.scene, case), spec, tpl.values(spec, case))


def _sim_values(fl: FlightSetup) -> dict[str, Any]:
    """What :func:`_pack` needs, read from the flight's Simulation (the reference set-up)."""
    sim = fl.sim
    fk = sim.fast_kernel
    return {"y0": sim.y, "kparams": fk.params, "force": fk.force, "torque": fk.torque, "burn": fk.burn,
            "mean_wind": sim.mean_wind_W, "gust": sim.gusts, "failures": sim.scheduled_failures, "copy_rng": True}


def fast_setup_agrees(spec: SweepSpec, fl: FlightSetup, n_steps: int = 4) -> bool:
    """Whether the fast set-up of flight ``fl`` packs bit for bit what its Simulation gives."""
    ref = setup_flight(spec, fl.index, nominal_scene(spec).vehicle.n_thrusters)
    # copy_rng: draw from a copy of the gust generator, so ``fl`` keeps its normals for the flight.
    fast = FlightSetup(fl.index, fl.case, None, fl.demand, spec, {**(fl.values or {}), "copy_rng": True})
    a, b = pack_flights([fast], n_steps), pack_flights([ref], n_steps)
    return ref.demand == fl.demand and all(
        a[k].dtype == b[k].dtype and a[k].shape == b[k].shape and a[k].tobytes() == b[k].tobytes() for k in b)


def pack_flights(flights: list[FlightSetup], n_steps: int, tpl: SetupTemplate | None = None) -> dict[str, np.ndarray]:
    """Arrays over flights for :func:`~.batched_kernel.fly_flights` (see its docstring)."""
    from lander_autopilot.controllers.base import Demand
    from lander_autopilot.controllers.compiled import N_DEMAND, demand_array

    F = len(flights)
    vals = [fl.values if fl.values is not None else _sim_values(fl) for fl in flights]
    n = vals[0]["force"].shape[0]
    n_fail = max([len(v["failures"]) for v in vals] + [1])
    a: dict[str, np.ndarray] = {
        "y0": np.zeros((F, 14)), "kparams": np.zeros((F, vals[0]["kparams"].size)),
        "force": np.zeros((F, n, 3)), "torque": np.zeros((F, n, 3)), "burn": np.zeros((F, n)),
        "mean_wind": np.zeros((F, 3)), "gust_ab": np.zeros((F, 3)), "gust_g0": np.zeros((F, 3)),
        "gust_w": np.zeros((F, n_steps, 3)), "fail_step": np.full((F, n_fail), -1, dtype=np.int64),
        "fail_thruster": np.zeros((F, n_fail), dtype=np.int64), "d_before": np.zeros((F, N_DEMAND)),
        "d_after": np.zeros((F, N_DEMAND)), "t_change": np.zeros(F),
    }
    for f, (fl, v) in enumerate(zip(flights, vals)):
        a["y0"][f] = v["y0"]
        a["kparams"][f] = v["kparams"]
        a["force"][f], a["torque"][f], a["burn"][f] = v["force"], v["torque"], v["burn"]
        a["mean_wind"][f] = v["mean_wind"]
        g = v["gust"]
        if g is not None:
            a["gust_ab"][f] = (1.0, g.a, g.b)
            a["gust_g0"][f] = g.gust_W
            # The normals GustProcess.advance would draw, three per step, from the same generator
            # (a copy when it is the Simulation's: it stays at its start for a touchdown hand-back).
            rng = g.rng
            if v.get("copy_rng"):
                rng = np.random.Generator(type(g.rng.bit_generator)())
                rng.bit_generator.state = g.rng.bit_generator.state
            rng.standard_normal(out=a["gust_w"][f])
        for q, (step, thruster) in enumerate(v["failures"]):
            a["fail_step"][f, q], a["fail_thruster"][f, q] = step, thruster
        before, after, t_change = fl.demand
        if tpl is not None:
            a["d_before"][f], a["d_after"][f] = tpl.demand(before), tpl.demand(after)
        else:
            d0, d1 = Demand(altitude=before), Demand(altitude=after)
            a["d_before"][f] = demand_array(d0.altitude, d0.attitude, d0.omega_B)
            a["d_after"][f] = demand_array(d1.altitude, d1.attitude, d1.omega_B)
        a["t_change"][f] = t_change
    return a


def pack_navigation(spec: SweepSpec, flights: list[FlightSetup], y0: np.ndarray, n_steps: int, dt: float) -> dict[str, np.ndarray]:
    """The :data:`~.batched_kernel.NAV_KEYS` arrays over ``flights`` (initial states ``y0``), as
    :func:`~.flight.navigator` sets a flight on the estimate up: the flight's own sensors (its scene's
    ``sensors``, seeded by its sensor seed, with its sensor dispersions) and the filter modelling the
    nominal scene's sensors (:func:`navigation_row`)."""
    scene0 = nominal_scene(spec)
    rows = []
    for fl, y in zip(flights, y0):
        sensors = fl.flown_scene().sensors
        rows.append(navigation_row(scene0, sensors, scene0.sensors, y, n_steps, dt))
    return stack_navigation(rows)


def navigation_row(scene: Any, sensors: Any, model: Any, y0: np.ndarray, n_steps: int, dt: float) -> tuple[np.ndarray, ...]:
    """One flight's :data:`~.batched_kernel.NAV_KEYS` arrays, as :class:`~lander_autopilot.estimation.
    onboard.Onboard` starts them: ``sensors`` (seeded) switched on (:class:`~lander_sim.sensors.suite.
    SensorSuite`; its generators then draw the normals of ``n_steps`` steps of ``dt`` [s]), and the
    filter modelling ``model``, started at the truth ``y0`` plus the error drawn from its ``P0`` with
    the initial-error generator of the sensors' seed; ``scene``'s inverse-square gravity."""
    from lander_autopilot.estimation.compiled import pack_filter
    from lander_autopilot.estimation.flights import INITIAL_SIGMA, initial_covariance, initial_error_rng, start_filter
    from lander_sim.sensors.compiled import pack_suite
    from lander_sim.sensors.suite import SensorSuite

    g = scene.models.get("gravity")
    gm, radius = float(g.gm), float(g.radius)
    sp, bias, w, off = pack_suite(SensorSuite(sensors), n_steps, dt, radius, gm)
    filt = start_filter(model, y0[0:3].copy(), y0[3:6].copy(), y0[6:10].copy(), 0.0,
                        initial_covariance(model, INITIAL_SIGMA), initial_error_rng(sensors.seed), gm, radius)
    return (sp, bias, w, off, *pack_filter(filt))


def stack_navigation(rows: list[tuple[np.ndarray, ...]]) -> dict[str, np.ndarray]:
    """:func:`navigation_row` rows as arrays over flights (the normals padded to the longest)."""
    w_all = np.zeros((len(rows), max(r[2].size for r in rows)))
    for f, r in enumerate(rows):
        w_all[f, :r[2].size] = r[2]
    cols = list(zip(*rows))
    return {"nav_sp": np.array(cols[0]), "nav_bias": np.array(cols[1]), "nav_w": w_all,
            "nav_off": np.array(cols[3], dtype=np.int64), "nav_x0": np.array(cols[4]), "nav_P0": np.array(cols[5]),
            "nav_qc": np.array(cols[6])}


def _finish_touchdown(fl: FlightSetup, out: dict[str, np.ndarray], f: int) -> tuple[float, dict[str, Any], float, float, float]:
    """Hand the touchdown step to the flight's Simulation: ``(speed, figures, altitude error, tilt, fuel)``
    of the interpolated state, as the per-flight loop sees it."""
    sim = fl.simulation()
    sim.drain_events()
    # The Simulation's own after-step checks: touchdown interpolation, classification, event.
    sim.adopt_step(out["y_prev_last"][f], out["y_last"][f], int(out["k_last"][f]))
    speed, figures = touchdown_speed_of(sim, out["v_before"][f].copy())
    st = sim.state()
    h, tilt = altitude_and_tilt(st.r_W, st.q)
    return speed, figures, h, tilt, float(st.fuel)


def fly_chunk(spec: SweepSpec, indices: Sequence[int], laws: list[Any] | None = None,
              parallel: bool = False, fast_setup: bool = True) -> list[dict[str, Any]]:
    """Rows of flights ``indices`` for every controller, flown on the batched core; ``parallel``
    runs the compiled loop over the flights on numba's threads (the sweep runner uses processes
    instead: the per-flight set-up is Python). ``fast_setup=False`` builds every flight's scene and
    Simulation (the reference set-up; the rows are the same)."""
    laws = laws if laws is not None else laws_of(spec)
    if laws is None:
        raise ValueError("fly_chunk: a controller of the spec has no compiled form (use the per-flight path)")
    navigating = [c.navigation == "estimate" for c in spec.controllers]
    if any(navigating) and len(indices) > NAV_CHUNK:  # the sensors' normals: about 150 B a step a flight
        return [row for part in chunks(indices, NAV_CHUNK) for row in fly_chunk(spec, part, laws, parallel, fast_setup)]
    scene0 = nominal_scene(spec)
    n_sub, period = control_period(spec, scene0.dt)
    n_ctrl = int(math.floor(spec.end.duration / period + 1e-9))
    flights: list[FlightSetup] = []
    rows: list[dict[str, Any]] = []
    broken: list[int] = []
    tpl = template_of(spec) if fast_setup else None
    if tpl is not None and tpl.why_not is not None:
        tpl = None
    for i in indices:
        try:
            if tpl is not None:
                flights.append(setup_flight_fast(spec, i, tpl))
            else:
                flights.append(setup_flight(spec, i, scene0.vehicle.n_thrusters))
        except Exception:  # noqa: BLE001 - the per-flight path makes the error row
            broken.append(i)
    if tpl is not None and flights and not fast_setup_agrees(spec, flights[0]):
        # Guard: the fast set-up must reproduce the reference one exactly (checked on each chunk's
        # first flight, one scene + Simulation a chunk); if not, set every flight up the reference way.
        tpl = None
        flights = [setup_flight(spec, fl.index, scene0.vehicle.n_thrusters) for fl in flights]
    if flights:
        inputs = pack_flights(flights, n_ctrl * n_sub, tpl)
        if tpl is not None:
            stop, dt = tpl.stop, tpl.dt
        else:
            sim0 = flights[0].sim
            stop, dt = (sim0.ground.contact_radius if sim0.ground is not None else 0.0), sim0.dt
        if any(navigating):
            inputs.update(pack_navigation(spec, flights, inputs["y0"], n_ctrl * n_sub, dt))
        for ci, law in enumerate(laws):
            params, K = law.pack()
            out = bk.fly_flights(inputs, params, K, n_ctrl, n_sub, period, dt, stop, parallel, navigation=navigating[ci])
            for f, fl in enumerate(flights):
                rows.append(_row(spec, ci, fl, out, f, period))
    for i in broken:
        rows.extend(fly_task(spec, ci, i) for ci in range(len(spec.controllers)))
    rows.sort(key=lambda r: (r["index"], r["controller_index"]))
    return rows


def _row(spec: SweepSpec, ci: int, fl: FlightSetup, out: dict[str, np.ndarray], f: int, period: float) -> dict[str, Any]:
    term = int(out["terminal"][f])
    if term == bk.TERM_ERROR:
        return fly_task(spec, ci, fl.index)
    ns = int(out["n_samples"][f])
    err, tilt = out["err"][f, :ns].copy(), out["tilt"][f, :ns].copy()
    rate = out["rate"][f, :ns].copy()
    fuel_end = float(out["fuel"][f, 1])
    before, after, t_change = fl.demand
    figures: dict[str, Any] = {}
    speed, terminal = math.nan, "ok"
    if term == bk.TERM_DIVERGED:
        terminal, fuel_end = "diverged", math.nan
    elif term == bk.TERM_TOUCHDOWN:
        if fl.simulation().phase.name != "FLYING":  # handed a touchdown already (another controller): start afresh
            fl.sim.reset()
        speed, figures, h, tilt_last, fuel_end = _finish_touchdown(fl, out, f)
        t_last = (ns - 1) * period
        err[-1] = h - (after if t_last >= t_change else before)
        tilt[-1], rate[-1] = tilt_last, 0.0
        terminal = "crashed" if fl.sim.phase.name == "CRASHED" else "landed"
    samples = Samples(
        t=np.arange(ns) * period, altitude_error=err, tilt=tilt, body_rate=rate,
        fuel_start=float(out["fuel"][f, 0]), fuel_end=fuel_end, saturated_updates=int(out["sats"][f]), period=period,
        touchdown_speed=speed, terminal=terminal, t_change=t_change, touchdown=figures,
    )
    return make_row(spec, ci, fl.index, fl.case, samples)


def chunks(indices: Sequence[int], size: int) -> Iterator[list[int]]:
    """``indices`` in consecutive chunks of at most ``size``."""
    idx = list(indices)
    for k in range(0, len(idx), max(1, size)):
        yield idx[k:k + size]


def fly_compiled(sim: Any, law: Any, demand_altitude: float, duration: float, n_sub: int = 1, copies: int = 1,
                 record_states: bool = False, parallel: bool = False, navigation: bool = False) -> dict[str, np.ndarray]:
    """The compiled closed loop of one flight: ``sim``'s scene from its current start, the law
    ``law`` (:class:`~lander_autopilot.controllers.compiled.CompiledLaw`) at a constant demand
    altitude [m], every ``n_sub`` physics steps, for ``duration`` [s]; ``navigation``: on the
    estimate of the scene's sensors (seeded as the scene says) and the filter modelling them.
    ``copies`` flies the same flight that many times in one call (for timing). Returns
    :func:`~.batched_kernel.fly_flights`'s arrays."""
    period = n_sub * sim.dt
    n_ctrl = int(math.floor(duration / period + 1e-9))
    inputs = pack_flights([FlightSetup(-1, FlightCase(-1, 0), sim, (demand_altitude, demand_altitude, 0.0))] * copies, n_ctrl * n_sub)
    if navigation:
        sensors = sim.scene.sensors
        inputs.update(stack_navigation([navigation_row(sim.scene, sensors, sensors, sim.y, n_ctrl * n_sub, sim.dt)] * copies))
    params, K = law.pack()
    stop = sim.ground.contact_radius if sim.ground is not None else 0.0
    return bk.fly_flights(inputs, params, K, n_ctrl, n_sub, period, sim.dt, stop, parallel, record_states, navigation)
