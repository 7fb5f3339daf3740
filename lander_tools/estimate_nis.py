"""NIS of a recorded flight on the estimate: the filter re-run over the bag's sensor messages (no rclpy).

The estimator node publishes the state after each tick's updates, not the updates' innovations. But
its estimate is a function of its inputs alone (docs/estimation.md, "Determinism without a new
message"): the scene (the sensors' schedule and noise model, the gravity), the initial-error seed
and sigmas, the flight's first state and the sensors' messages, which the bag holds. So
``lander analyse`` runs the same :class:`~lander_autopilot.estimation.ticks.TickFeeder` over the
recorded sensor messages, as the node did (:func:`replay`), and keeps every update's innovation.

**The check.** The re-run is trusted only where it *is* the recorded flight's filter: at every
state its Odometry, computed by the node's own conversion
(:func:`lander_autopilot.ros.estimator_convert.fill_odometry`), must equal the recorded
``/lander/estimate/odometry`` bit for bit: position, orientation, linear and angular twist, the pose
covariance (the filter's ``P`` over ``[dr, dth]``, copied) and the twist covariance (``R P_vv R^T``,
and the gyro bias's ``P_bg`` plus the variance of the gyro reading the filter last applied). The
first state that differs ends the re-run and NIS is n/a, with the state and the
field named (another seed or initial sigmas than the bag's metadata says, another estimator
version, a tampered estimate).

**Setup from the bag** (:func:`setup_from_meta`): the scene is the metadata's ``scene`` (``lander
fly`` writes it); the seed its ``seed`` where the flight set the simulator's (a scripted flight's
``sim`` section, a sweep), else the scene's ``sensors.seed``, which is what ``lander fly`` gives
the estimator (the simulator's seed, -1 meaning the scene's); the initial sigmas the estimator's
defaults (:mod:`lander_autopilot.ros.estimator_config`; ``lander fly`` sets no others).

**NIS** of an update with innovation ``y`` (``p`` components) and predicted covariance
``S = H P H^T + R`` (:class:`lander_autopilot.estimation.ekf.Update`)::

    nis = y^T S^-1 y        ~ chi-square(p) for a consistent filter

and a consistent filter's innovations are white, so the ``N`` values of one sensor are independent
and ``N`` times their average is chi-square with ``N p`` degrees of freedom: the time average has
the exact 95 % interval ``[chi2(0.025; N p), chi2(0.975; N p)] / N``
(:func:`lander_autopilot.estimation.consistency.anis`; Bar-Shalom, Li and Kirubarajan, *Estimation
with Applications to Tracking and Navigation*, 2001, section 5.4). Each value against the
single-update interval ``[chi2(0.025; p), chi2(0.975; p)]``: 95 % of them inside for a consistent
filter.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from lander_autopilot.estimation.ekf import Update
from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_autopilot.estimation.ticks import Reading, TickFeeder
from lander_ros.flight_span import SENSOR_KEYS, SENSOR_TOPICS
from lander_tools.chi_square import ChiSquareSummary

#: The recorded estimate the re-run is checked against.
ODOMETRY_TOPIC = "/lander/estimate/odometry"
STATE_TOPIC = "/lander/state"
#: Single-update and time-average intervals' probability.
PROB = 0.95


#: Why a bag without the IMU's messages has no NIS.
NO_IMU = ("the bag holds no /lander/sensors/imu message, so the filter cannot be re-run (lander fly --estimate "
          "--record records the sensor topics)")


class NisUnavailable(Exception):
    """Why NIS cannot be reported for a bag (one line)."""


@dataclass(frozen=True)
class FilterSetup:
    """What the estimator node was started with (module docstring, "Setup from the bag"): ``scene``
    (name, alias or path), the initial-error ``seed`` (None: the scene's ``sensors.seed``) and the
    initial sigmas ``(position [m], velocity [m/s], attitude [rad])``."""

    scene: str
    seed: int | None
    initial_sigma: tuple[float, float, float]

    def describe(self) -> str:
        seed = "the scene's sensors.seed" if self.seed is None else str(self.seed)
        return f"scene {self.scene}, seed {seed}"


def setup_from_meta(meta: dict[str, str]) -> FilterSetup:
    """The :class:`FilterSetup` of a bag's ``custom_data`` (module docstring)."""
    from lander_autopilot.ros.estimator_config import SCENE_SEED, SPECS, initial_sigma

    scene = meta.get("scene", "").strip()
    if not scene:
        raise NisUnavailable("the bag's metadata names no scene, so the filter cannot be re-run")
    raw = meta.get("seed", str(SCENE_SEED)).strip()
    try:
        seed = int(raw)
    except ValueError:
        raise NisUnavailable(f"the bag's metadata seed {raw!r} is not an integer") from None
    sigma = initial_sigma({name: spec.default for name, spec in SPECS.items()})
    return FilterSetup(scene=scene, seed=None if seed == SCENE_SEED else seed, initial_sigma=sigma)


#: A check of the re-run's filter after tick ``k`` (0-based): None when it matches, else why not.
TickCheck = Callable[[int, TickFeeder], "str | None"]


@dataclass
class Replay:
    """The re-run: ``ticks`` run (and checked), and every update with its tick's time [s]."""

    ticks: int
    updates: list[tuple[float, Update]]


def replay(feeder: TickFeeder, readings: Iterable[Reading], ticks_ns: Sequence[int],
           check: TickCheck | None = None) -> Replay:
    """Run ``feeder`` (started: :meth:`TickFeeder.start`) over ``readings`` a tick at a time, the
    ticks at the stamps ``ticks_ns`` [ns], as the estimator node does; after each tick ``check``
    (None: none). Raises :class:`NisUnavailable` when a tick lacks a reading or the check fails."""
    # each tick's readings are added just before it, as they reach the node: the feeder's queues
    # then hold about one tick's readings (added all at once, every tick would walk them all)
    pending = sorted(readings, key=lambda r: r.t_ns)
    i = 0
    out: list[tuple[float, Update]] = []
    for k, t_ns in enumerate(ticks_ns):
        while i < len(pending) and pending[i].t_ns <= t_ns:
            feeder.add(pending[i])
            i += 1
        if not feeder.ready(t_ns):
            raise NisUnavailable(f"state {k + 1} (t = {t_ns * 1e-9:.6g} s): the bag lacks a sensor reading of its "
                                 "tick (a sensor topic not recorded, or the bag cut short)")
        out += [(t_ns * 1e-9, u) for u in feeder.advance(t_ns)]
        if check is not None:
            why = check(k, feeder)
            if why is not None:
                raise NisUnavailable(why)
    return Replay(ticks=len(ticks_ns), updates=out)


# --- the check against the recorded Odometry -------------------------------------------------------


def odometry_message() -> Any:
    """A message-shaped namespace that :func:`~lander_autopilot.ros.estimator_convert.fill_odometry` fills."""
    def vec() -> SimpleNamespace:
        return SimpleNamespace(x=0.0, y=0.0, z=0.0)
    return SimpleNamespace(header=SimpleNamespace(stamp=None),
                           pose=SimpleNamespace(pose=SimpleNamespace(position=vec(), orientation=SimpleNamespace(
                               x=0.0, y=0.0, z=0.0, w=1.0)), covariance=[]),
                           twist=SimpleNamespace(twist=SimpleNamespace(linear=vec(), angular=vec()), covariance=[]))


def odometry_fields(msg: Any) -> dict[str, bytes]:
    """The compared fields of an Odometry (recorded or re-run) as float64 bytes, by name."""
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular

    def b(values: Any) -> bytes:
        return np.asarray(values, dtype=np.float64).tobytes()
    return {
        "position": b((p.x, p.y, p.z)), "orientation": b((o.x, o.y, o.z, o.w)),
        "twist.linear": b((lin.x, lin.y, lin.z)), "twist.angular": b((ang.x, ang.y, ang.z)),
        "pose.covariance": b(msg.pose.covariance),
        "twist.covariance": b(msg.twist.covariance),
    }


def odometry_check(states: Sequence[Any], recorded: Sequence[Any]) -> TickCheck:
    """A :data:`TickCheck`: the re-run's Odometry at tick ``k`` equals ``recorded[k]`` field for field,
    bit for bit (module docstring); ``states[k]`` is the truth the node answered."""
    from lander_autopilot.ros import estimator_convert as convert

    mine = odometry_message()

    def check(k: int, feeder: TickFeeder) -> str | None:
        assert feeder.filter is not None
        convert.fill_odometry(mine, states[k], feeder.estimate(), feeder.filter, feeder.omega_var)
        got, want = odometry_fields(mine), odometry_fields(recorded[k])
        bad = [name for name in want if got[name] != want[name]]
        if not bad:
            return None
        t = convert.stamp_ns(states[k].header.stamp) * 1e-9
        return (f"the re-run does not reproduce the recorded estimate: state {k + 1} (t = {t:.6g} s) differs in "
                f"{', '.join(bad)}")
    return check


# --- NIS per sensor --------------------------------------------------------------------------------


@dataclass(frozen=True)
class SensorNis(ChiSquareSummary):
    """One sensor's NIS (module docstring): the time average against its bounds
    (:class:`~lander_tools.chi_square.ChiSquareSummary`: ``mean``, ``dof``, ``samples`` updates, the
    interval for that many independent values ``bounds``, the single-update interval
    ``bounds_one`` and the fraction inside it), with the times ``t`` [s] (the tick of each update)
    and the ``values``."""

    sensor: str
    t: np.ndarray
    values: np.ndarray


def sensor_nis(updates: Sequence[tuple[float, Update]], prob: float = PROB) -> dict[str, SensorNis]:
    """Per sensor (in the sensor table's order), the :class:`SensorNis` of ``updates``."""
    out: dict[str, SensorNis] = {}
    for key in SENSOR_KEYS:
        mine = [(t, u) for t, u in updates if u.key == key]
        if not mine:
            continue
        values = np.array([u.nis for _, u in mine])
        out[key] = SensorNis.of(values, len(mine[0][1].y), prob, sensor=key, t=np.array([t for t, _ in mine]),
                                values=values)
    return out


@dataclass
class NisReport:
    """NIS of a bag's flight: the re-run's ``setup``, ``states`` checked bit for bit (every state
    with a recorded estimate, from the flight's first), its wall time
    ``wall_s`` [s], and per sensor :class:`SensorNis`."""

    setup: FilterSetup
    states: int
    wall_s: float
    sensors: dict[str, SensorNis]

    def summary(self) -> dict[str, Any]:
        return {k: {"dof": s.dof, "updates": s.samples, "mean": s.mean, "bounds": list(s.bounds),
                    "bounds_single_update": list(s.bounds_one), "frac_inside": s.frac_inside}
                for k, s in self.sensors.items()}

    def rerun_summary(self) -> dict[str, Any]:
        return {"scene": self.setup.scene, "seed": self.setup.seed, "initial_sigma": list(self.setup.initial_sigma),
                "states_reproduced": self.states, "wall_s": self.wall_s}

    def lines(self) -> list[str]:
        out = [f"  NIS: the filter re-run over the bag's sensor messages ({self.setup.describe()}) reproduces the "
               f"recorded estimate bit for bit at every one of its {self.states} states ({self.wall_s:.1f} s)"]
        if not self.sensors:
            return out + ["  NIS: no update in the flight (every aiding sensor out of range)"]
        head = ["NIS", "dof", "updates", "mean", "95 % (independent updates)", "95 % (single update)", "updates inside"]
        rows = [[k, str(s.dof), str(s.samples), *s.cells()] for k, s in self.sensors.items()]
        widths = [max(len(x) for x in col) for col in zip(head, *rows)]
        fmt = "  " + "  ".join(f"{{:<{w}}}" for w in widths)
        return out + [fmt.format(*head).rstrip()] + [fmt.format(*r).rstrip() for r in rows]


def _last_flight(messages: list[Any], stamp: Callable[[Any], int]) -> list[Any]:
    """The messages after the last reset (a stamp not after the one before), as the analysis keeps."""
    k = 0
    for i in range(1, len(messages)):
        if stamp(messages[i]) <= stamp(messages[i - 1]):
            k = i
    return messages[k:]


def from_bag(bag: Any) -> NisReport:
    """Re-run the estimator over ``bag``'s last flight (module docstring) and report NIS; raises
    :class:`NisUnavailable` with the reason when it cannot or the re-run differs."""
    from lander_autopilot.ros import estimator_convert as convert
    from lander_sim.scenes import SceneError, load_scene

    t0 = time.perf_counter()
    if not bag.messages("/lander/sensors/imu"):
        raise NisUnavailable(NO_IMU)
    setup = setup_from_meta(bag.meta)
    try:
        scene = load_scene(setup.scene)
    except (SceneError, OSError) as exc:
        raise NisUnavailable(f"the bag's scene {setup.scene!r} cannot be loaded here: {exc}") from None
    g = scene.models.get("gravity")
    if scene.sensors is None or "imu" not in scene.sensors or g is None or g.kind != "inverse-square":
        raise NisUnavailable(f"scene {scene.name!r} (the bag's metadata) has no IMU or no inverse-square "
                             "gravity: not a scene the estimator runs")

    def stamp(m: Any) -> int:
        return convert.stamp_ns(m.header.stamp)

    states = _last_flight(bag.messages(STATE_TOPIC), stamp)
    recorded = _last_flight(bag.messages(ODOMETRY_TOPIC), stamp)
    if not states or states[0].sequence != 1:
        raise NisUnavailable("the bag's last flight does not start at its first state (sequence 1), where the "
                             "estimator starts its filter")
    n = min(len(states), len(recorded))
    if n == 0 or [stamp(m) for m in states[:n]] != [stamp(m) for m in recorded[:n]]:
        raise NisUnavailable(f"{ODOMETRY_TOPIC} does not hold one estimate per state with the state's stamp")
    readings: list[Reading] = []
    for key, topic in zip(SENSOR_KEYS, SENSOR_TOPICS):
        if key in scene.sensors:
            try:
                readings += [convert.reading(key, m) for m in _last_flight(bag.messages(topic), stamp)]
            except (AttributeError, TypeError, ValueError, IndexError) as exc:
                raise NisUnavailable(f"{topic} cannot be read as the simulator's sensor message "
                                     f"({type(exc).__name__}: {exc})") from None
    s0 = states[0]
    p, v, o = s0.position, s0.velocity, s0.orientation
    seed = scene.sensors.seed if setup.seed is None else setup.seed
    feeder = TickFeeder(scene.sensors)
    feeder.start(start_filter(scene.sensors, np.array((p.x, p.y, p.z)), np.array((v.x, v.y, v.z)),
                              np.array((o.w, o.x, o.y, o.z)), stamp(s0) * 1e-9,
                              initial_covariance(scene.sensors, setup.initial_sigma), initial_error_rng(seed),
                              float(g.gm), float(g.radius)))
    try:
        run = replay(feeder, readings, [stamp(m) for m in states[:n]], odometry_check(states, recorded))
    except NisUnavailable as exc:
        raise NisUnavailable(f"{exc} ({setup.describe()})") from None
    return NisReport(setup=setup, states=run.ticks, wall_s=time.perf_counter() - t0, sensors=sensor_nis(run.updates))


# --- figure ----------------------------------------------------------------------------------------


def figure(name: str, rep: NisReport) -> Any:
    """NIS of each sensor's updates against time (log scale) with its single-update 95 % interval
    (dashed) and its time average (solid), one row per sensor."""
    from lander_tools import plotstyle as ps

    plt = ps.pyplot()
    rows = max(1, len(rep.sensors))
    fig, axes = plt.subplots(rows, 1, sharex=True, figsize=(8, 2.3 * rows + 1.0), layout="constrained",
                             squeeze=False)
    for i, (key, s) in enumerate(rep.sensors.items()):
        ax = axes[i, 0]
        ax.semilogy(s.t, np.clip(s.values, 1e-6, None), ".", ms=2.5, color=ps.colour(i), label=f"NIS {key}")
        for b in s.bounds_one:
            ax.axhline(b, color="0.3", ls="--", lw=1.0)
        ax.axhline(s.mean, color="k", lw=1.0)
        ax.set_ylabel(f"NIS {key} ({s.dof} dof)")
        ax.set_title(f"{key}: {len(s.values)} updates, mean {s.mean:.3g} (95 %: [{s.bounds[0]:.3g}, "
                     f"{s.bounds[1]:.3g}]), {100 * s.frac_inside:.1f} % inside [{s.bounds_one[0]:.3g}, "
                     f"{s.bounds_one[1]:.3g}]", fontsize="small")
        ax.set_xlabel("simulation time [s]")
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.grid(True)
    fig.suptitle(f"{name}: NIS per sensor, single-update chi-square 95 % interval dashed, time average solid",
                 fontsize="medium")
    return fig
