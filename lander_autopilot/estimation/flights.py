"""Core flights with the navigation filter alongside (no ROS): the consistency Monte Carlo's runs.

A flight here is the simulator stepping a scene while its autopilot flies on the **truth**; each
step the sensors the scene switches on (:mod:`lander_sim.sensors`) sample the truth and the filter
(:mod:`.ekf`) takes their measurements. It measures whether the filter's covariance tells the truth
about its errors (flying the autopilot on the estimate is a different experiment). Order within a
step from ``t_k`` to ``t_k+1``::

    throttles from the controller at t_k -> the simulation steps to t_k+1 -> the truth at t_k+1,
    with the IMU's body rate and specific force averaged over the step -> the sensors due at
    t_k+1 -> the filter propagated to t_k+1 with the IMU sample -> aiding updates -> NEES at t_k+1

The initial estimate is the truth plus an error drawn from the initial covariance ``P0``, and the
initial bias estimates are 0 with the IMU's switch-on bias variances: so the filter starts
consistent by construction, and what the test measures is whether it stays so.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from lander_sim.physics.rotation import quat_mult
from lander_sim.physics.state import StateView
from lander_sim.scenes.loader import Scene
from lander_sim.sensors.base import Measurement
from lander_sim.sensors.imu import IMU
from lander_sim.sensors.suite import SensorsConfig, SensorSuite
from lander_sim.sensors.truth import truth_after_step
from lander_sim.simulation import Simulation

from ..controllers import Demand, make_controller
from .consistency import error_state, nees
from .ekf import NavFilter, NavState, NoiseModel, small_rotation

#: Initial estimation errors (1 sigma): 10 m of position, 0.5 m/s of velocity, 1 degree of attitude
#: per axis: a lander handed over from an approach solution and a star-tracker fix.
INITIAL_SIGMA = (10.0, 0.5, np.radians(1.0))


@dataclass
class FlightRecord:
    """One flight: times ``t`` (K), NEES (K), errors and filter sigmas (K x 15), and the NIS of each
    sensor's updates (key -> list of ``(nis, dof)``)."""

    t: list[float] = field(default_factory=list)
    nees: list[float] = field(default_factory=list)
    errors: list[np.ndarray] = field(default_factory=list)
    sigmas: list[np.ndarray] = field(default_factory=list)
    nis: dict[str, list[tuple[float, int]]] = field(default_factory=dict)
    end: str = ""


def initial_covariance(sensors: SensorsConfig, sigma: tuple[float, float, float] = INITIAL_SIGMA) -> np.ndarray:
    """``P0`` (15 x 15): ``sigma`` for position, velocity, attitude; the IMU's switch-on bias variances."""
    imu = sensors.sections["imu"]
    d = np.repeat([sigma[0] ** 2, sigma[1] ** 2, sigma[2] ** 2, float(imu["gyro_bias"]) ** 2,
                   float(imu["accel_bias"]) ** 2], 3)
    return np.diag(d)


def make_filter(sensors: SensorsConfig, sim: Simulation, P0: np.ndarray, rng: np.random.Generator) -> NavFilter:
    """A filter started at the truth plus an error drawn from ``P0`` (biases: estimate 0)."""
    g = sim.scene.models.get("gravity")
    if g is None or g.kind != "inverse-square":
        raise ValueError(f"scene {sim.scene.name}: the filter's gravity model needs models.gravity.kind: inverse-square")
    y = sim.y
    return start_filter(sensors, y[0:3], y[3:6], y[6:10], sim.t, P0, rng, float(g.gm), float(g.radius))


def start_filter(sensors: SensorsConfig, r_W: np.ndarray, v_W: np.ndarray, q: np.ndarray, t: float,
                 P0: np.ndarray, rng: np.random.Generator, gm: float, planet_radius: float) -> NavFilter:
    """A filter at time ``t`` [s] started at the true ``r_W``, ``v_W``, ``q`` plus an error drawn from
    ``P0`` (biases: estimate 0); ``gm`` [m^3/s^2] and ``planet_radius`` [m]: the scene's gravity."""
    imu = sensors.sections["imu"]
    noise = NoiseModel(float(imu["gyro_noise_density"]), float(imu["accel_noise_density"]),
                       float(imu["gyro_bias_walk"]), float(imu["accel_bias_walk"]))
    sd = np.sqrt(np.diag(P0))
    n = rng.standard_normal(9)
    # truth = estimate + error, so the estimate is truth - error (the attitude: q_true = q_est x dq(th))
    th = sd[6:9] * n[6:9]
    q_est = quat_mult(q, small_rotation(-th))
    state = NavState(r_W=r_W - sd[0:3] * n[0:3], v_W=v_W - sd[3:6] * n[3:6], q=q_est,
                     b_g=np.zeros(3), b_a=np.zeros(3), P=P0.copy(), t=t)
    return NavFilter(state, noise, gm=gm, planet_radius=planet_radius)


def initial_error_rng(seed: int) -> np.random.Generator:
    """The generator of the initial estimation error for sensor seed ``seed`` (apart from the sensors' own)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, 1000])))


def _apply(filt: NavFilter, m: Measurement, sensors: SensorsConfig, rec: FlightRecord) -> None:
    if m.key == "star_tracker":
        u = filt.update_star_tracker(m.z, m.sigma)
    elif m.key == "altimeter":
        beam = np.array(sensors.sections["altimeter"]["beam_B"], float)
        u2 = filt.update_altimeter(float(m.z[0]), float(m.sigma[0]), beam)
        if u2 is None:
            return
        u = u2
    elif m.key == "doppler":
        u = filt.update_doppler(m.z, m.sigma)
    elif m.key == "ground_fix":
        u = filt.update_ground_fix(m.z, m.sigma)
    else:
        return
    rec.nis.setdefault(m.key, []).append((u.nis, len(u.y)))


def fly(scene: Scene, seed: int, duration: float, demand: Demand | None = None,
        initial_sigma: tuple[float, float, float] = INITIAL_SIGMA) -> FlightRecord:
    """Fly ``scene`` (its autopilot on the truth, ``demand`` by default its demand altitude; no
    autopilot: the thrusters stay off) for ``duration`` [s] or until it lands, with the filter
    alongside; sensors and initial error from ``seed``."""
    if scene.sensors is None or "imu" not in scene.sensors:
        raise ValueError(f"scene {scene.name}: the filter needs sensors.imu switched on")
    sensors = dataclasses.replace(scene.sensors, seed=seed)
    sim = Simulation(scene)
    suite = SensorSuite(sensors)
    ap = scene.autopilot
    ctrl = None if ap is None else make_controller(ap.controller, scene.vehicle, **dict(ap.parameters))
    if demand is None:
        alt = None if ap is None else ap.demand_altitude
        demand = Demand(altitude=500.0 if alt is None else alt)
    P0 = initial_covariance(sensors, initial_sigma)
    filt = make_filter(sensors, sim, P0, initial_error_rng(seed))
    imu = suite.sensors["imu"]
    assert isinstance(imu, IMU)  # SENSORS maps "imu" to it
    rec = FlightRecord()
    while sim.t < duration - 1e-9 and sim.phase.name == "FLYING":
        if ctrl is not None:
            state: StateView = sim.state()
            sim.set_throttles(ctrl.update(sim.t, state, demand).throttles)
        y_before = sim.y.copy()
        t_before = sim.t
        sim.step()
        if sim.phase.name != "FLYING":
            break  # the step ended at the touchdown, inside it: no full interval for the IMU
        truth = truth_after_step(sim, y_before, sim.t - t_before)
        ms = suite.sample(truth)
        if not ms or ms[0].key != "imu":
            raise ValueError("the IMU gave no sample this step: its rate must be at least the simulation's step rate")
        filt.propagate(ms[0].z[0:3], ms[0].z[3:6], sim.t - t_before)
        for m in ms[1:]:
            _apply(filt, m, sensors, rec)
        e = error_state(filt.state, truth.r_W, truth.v_W, truth.q,
                        imu.gyro_bias.value, imu.accel_bias.value)
        rec.t.append(sim.t)
        rec.errors.append(e)
        rec.sigmas.append(np.sqrt(np.diag(filt.state.P)))
        rec.nees.append(nees(e, filt.state.P))
    rec.end = sim.phase.name
    return rec
