"""Flying on the estimate in the core: the sensors and the navigation filter riding along a Simulation.

:class:`Onboard` does, without ROS, what the simulator node's sensors and the estimator node do
together (docs/estimation.md, "On ROS: the estimator node"):

* at the flight's first instant the sensors sample the truth of that instant
  (:func:`lander_sim.sensors.truth.truth_of`, the throttles as set for the coming step) and the
  filter starts at the truth plus an error drawn from ``P0`` with the initial-error generator of
  ``seed`` (:func:`.flights.start_filter`, :func:`.flights.initial_error_rng`);
* after every physics step the sensors sample the step (:func:`~lander_sim.sensors.truth.truth_after_step`)
  and each due sample, a dropout included, becomes a :class:`~.ticks.Reading` stamped in integer
  nanoseconds ``round(t 1e9)`` (the stamps' resolution on ROS);
* at a control tick :class:`~.ticks.TickFeeder` applies the tick's readings in its fixed order
  (propagate on each step's IMU reading, then the aiding updates of that step), and the estimate
  becomes the :class:`~lander_sim.physics.state.StateView` a controller is given: position,
  velocity, attitude, ZXZ angles and body rate ``omega_m - b_g`` from the filter, the fuel from the
  simulation (what the lander knows of itself without navigating, as the estimator's state message).

A controller flown on :meth:`Onboard.state` in place of ``Simulation.state()`` flies on the estimate
and on nothing else of the truth but its fuel; :func:`fly_on_estimate` flies a scene's autopilot so.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from lander_sim.errors import InputError
from lander_sim.physics.state import FUEL, StateView
from lander_sim.scenes.loader import Scene
from lander_sim.sensors.base import Truth
from lander_sim.sensors.suite import SensorsConfig, SensorSuite
from lander_sim.sensors.truth import truth_after_step, truth_of
from lander_sim.simulation import Simulation

from ..controllers import Demand, make_controller
from ..controllers.base import REQUEST_DEPLOY_PARACHUTE, Controller
from .compiled import compiled_copy
from .flights import INITIAL_SIGMA, initial_covariance, initial_error_rng, start_filter
from .ticks import Reading, TickFeeder


def stamp_ns(t: float) -> int:
    """Sim time ``t`` [s] as integer nanoseconds, rounded to nearest (a ROS stamp's resolution)."""
    return int(round(t * 1e9))


class Onboard:
    """The sensors of ``sensors`` (seeded with ``seed``; None: the section's own) and a filter fed from
    them along ``sim``, from its present instant, which must be the flight's first (module docstring).

    Step the simulation with :meth:`step` (one physics step at a time, each sampled), and read the
    estimate at a control tick with :meth:`state`. ``initial_sigma``: the initial estimation errors
    (1 sigma: position [m], velocity [m/s], attitude [rad]). ``compiled``: the filter with its
    covariance steps compiled (:class:`.compiled.CompiledNavFilter`, the same filter to rounding,
    faster) instead of :class:`~.ekf.NavFilter` (the estimator node's, to the bit). ``model``: the
    sensors as the filter models them (the IMU's noise densities and bias walks, and its switch-on
    bias variances in ``P0``; the rates must be the flown ones), default ``sensors`` themselves."""

    def __init__(self, sim: Simulation, sensors: SensorsConfig, seed: int | None = None,
                 initial_sigma: tuple[float, float, float] = INITIAL_SIGMA, compiled: bool = False,
                 model: SensorsConfig | None = None) -> None:
        if "imu" not in sensors.sections:
            raise ValueError(f"scene {sim.scene.name}: flying on the estimate needs sensors.imu switched on")
        g = sim.scene.models.get("gravity")
        if g is None or g.kind != "inverse-square":
            raise ValueError(f"scene {sim.scene.name}: the filter's gravity model needs models.gravity.kind: inverse-square")
        rate = float(sensors.sections["imu"]["rate"])
        if rate * sim.dt < 1.0 - 1e-9:
            raise ValueError(f"scene {sim.scene.name}: sensors.imu.rate ({rate:g} Hz) must sample every "
                             f"{sim.dt:g} s step: the filter propagates on each step's IMU reading")
        self.seed = sensors.seed if seed is None else int(seed)
        self.sensors = dataclasses.replace(sensors, seed=self.seed)
        self.sim = sim
        self.suite = SensorSuite(self.sensors)
        self.feeder = TickFeeder(self.sensors)
        truth = truth_of(sim)
        self._feed(truth)
        believed = self.sensors if model is None else model
        if {k: v["rate"] for k, v in believed.sections.items()} != {k: v["rate"] for k, v in sensors.sections.items()}:
            raise ValueError("the filter's model of the sensors must have the flown sensors and rates")
        P0 = initial_covariance(believed, initial_sigma)
        filt = start_filter(believed, truth.r_W, truth.v_W, truth.q, sim.t, P0, initial_error_rng(self.seed),
                            float(g.gm), float(g.radius))
        self.feeder.start(compiled_copy(filt) if compiled else filt)

    def _feed(self, truth: Truth) -> None:
        t_ns = stamp_ns(truth.t)
        for key, m in self.suite.sample_due(truth):
            self.feeder.add(Reading(key, t_ns) if m is None else Reading(key, t_ns, m.z, m.sigma))

    def step(self, n: int = 1) -> None:
        """Advance the simulation ``n`` steps one at a time, the sensors sampling each; none after
        the lander is down (the step that reaches the ground ends inside it)."""
        sim = self.sim
        for _ in range(n):
            if sim.phase.name != "FLYING":
                sim.step(1)
                continue
            y_before, t_before = sim.y.copy(), sim.t
            sim.step(1)
            if sim.phase.name == "FLYING":
                self._feed(truth_after_step(sim, y_before, sim.t - t_before))

    def state(self, t: float | None = None) -> StateView:
        """The estimate at the simulation's present instant (every reading up to it applied) as the
        state a controller reads; ``t`` [s] its time stamp (default the simulation's)."""
        sim = self.sim
        t_ns = stamp_ns(sim.t)
        if not self.feeder.ready(t_ns):
            raise RuntimeError(f"t = {sim.t} s: the readings of the tick are not all in")
        self.feeder.advance(t_ns)
        e = self.feeder.estimate()
        return StateView(t=sim.t if t is None else t, r_W=e.r_W, v_W=e.v_W, q=e.q, euler=np.asarray(e.euler, float),
                         omega_B=e.omega_B, fuel=float(sim.y[FUEL]))


@dataclass
class EstimateFlight:
    """A flight on the estimate: control instants ``t`` [s], the throttles applied over each period,
    the true and estimated positions ``r_W`` [m] at each instant, and the flight's end phase."""

    t: list[float] = field(default_factory=list)
    throttles: list[np.ndarray] = field(default_factory=list)
    r_true: list[np.ndarray] = field(default_factory=list)
    r_estimate: list[np.ndarray] = field(default_factory=list)
    end: str = ""


def fly_on_estimate(scene: Scene, duration: float, seed: int | None = None, demand: Demand | None = None,
                    steps_per_control: int = 1, compiled: bool = False, controller: Controller | None = None,
                    initial_sigma: tuple[float, float, float] = INITIAL_SIGMA) -> EstimateFlight:
    """Fly a law on the estimate (:class:`Onboard`, sensors seeded with ``seed``; None: the scene's)
    for ``duration`` [s] or until the lander is down: at every ``steps_per_control`` physics steps (the
    control instants ``t_k = k n dt``) the law is given the estimate, its throttles are set and its
    parachute request is acted on as the autopilot node does. ``controller``: the law (default the
    scene's autopilot built on the scene's vehicle); ``demand``: default the scene's demand altitude
    (500 m without one)."""
    ap = scene.autopilot
    if scene.sensors is None:
        raise ValueError(f"scene {scene.name}: flying on the estimate needs sensors.imu switched on")
    if controller is None:
        if ap is None:
            raise ValueError(f"scene {scene.name}: no autopilot to fly on the estimate")
        controller = make_controller(ap.controller, scene.vehicle, **dict(ap.parameters))
    ctrl = controller
    sim = Simulation(scene)
    onboard = Onboard(sim, scene.sensors, seed, initial_sigma, compiled)
    if demand is None:
        alt = None if ap is None else ap.demand_altitude
        demand = Demand(altitude=500.0 if alt is None else alt)
    period = steps_per_control * sim.dt
    rec = EstimateFlight()
    k = 0
    while k * period < duration - 1e-9 and sim.phase.name == "FLYING":
        t = k * period
        est = onboard.state()
        out = ctrl.update(t, est, demand)
        for req in out.requests:
            if req.kind == REQUEST_DEPLOY_PARACHUTE:
                try:
                    sim.deploy_parachute()
                except InputError:
                    pass  # a scene without a parachute refuses, as the simulator node's service does
        sim.set_throttles(out.throttles)
        rec.t.append(t)
        rec.r_true.append(sim.y[0:3].copy())
        rec.r_estimate.append(est.r_W.copy())
        onboard.step(steps_per_control)
        rec.throttles.append(sim.throttles)
        k += 1
    rec.end = sim.phase.name
    return rec
