"""The filter fed a control tick at a time (lander_autopilot.estimation.ticks.TickFeeder), without ROS.

The readings are the core SensorSuite's over a core flight of landing-sensors (scenario 1 from 10 km:
the altimeter and the Doppler out of range, so every tick of theirs is a "no reading"), stamped in
integer nanoseconds as the messages carry them. The contracts the estimator node relies on:

* a tick is ready exactly when the last reading the schedule says it brings is in, whatever the
  order the sensors' readings come in (each sensor's own in order, as one writer delivers them);
* the estimate is the same bits for every such order;
* the suite's sampling is its schedule: ``sample`` is ``sample_due`` less the dropouts;
* a tick ending on a step the IMU is not due at (a touchdown inside a step) is ready without one.
"""
from __future__ import annotations

import random

import numpy as np
import pytest

from lander_autopilot.estimation.flights import initial_covariance, initial_error_rng, start_filter
from lander_autopilot.estimation.ticks import Reading, TickFeeder
from lander_ros.stamps import sim_time_to_ns
from lander_sim.scenes import load_scene
from lander_sim.sensors.suite import SampleSchedule, SensorSuite
from lander_sim.sensors.truth import truth_after_step, truth_of
from lander_sim.simulation import Simulation

#: Physics steps per control tick (landing-sensors: dt 0.01 s, control at 50 Hz).
STEPS_PER_TICK = 2
TICKS = 150


def _readings(suite: SensorSuite, truth) -> list[Reading]:
    return [Reading(k, sim_time_to_ns(truth.t), None if m is None else m.z, None if m is None else m.sigma)
            for k, m in suite.sample_due(truth)]


@pytest.fixture(scope="module")
def flight():
    """(scene, initial state, [(tick stamp ns, the tick's readings in publishing order)])."""
    scene = load_scene("landing-sensors")
    sim = Simulation(scene)
    suite = SensorSuite(scene.sensors)
    y0 = sim.y.copy()
    ticks = [(0, _readings(suite, truth_of(sim)))]
    for _ in range(TICKS):
        rs: list[Reading] = []
        for _ in range(STEPS_PER_TICK):
            y, t = sim.y.copy(), sim.t
            sim.step()
            rs += _readings(suite, truth_after_step(sim, y, sim.t - t))
        ticks.append((sim_time_to_ns(sim.t), rs))
    return scene, y0, ticks


def _feeder(scene, y0) -> TickFeeder:
    g = scene.models.get("gravity")
    f = TickFeeder(scene.sensors)
    f.start(start_filter(scene.sensors, y0[0:3], y0[3:6], y0[6:10], 0.0, initial_covariance(scene.sensors),
                         initial_error_rng(scene.sensors.seed), float(g.gm), float(g.radius)))
    return f


def _interleave(rs: list[Reading], rng: random.Random) -> list[Reading]:
    """The readings in a random order across sensors, each sensor's own in order."""
    keys = [r.key for r in rs]
    rng.shuffle(keys)
    by: dict[str, list[Reading]] = {}
    for r in rs:
        by.setdefault(r.key, []).append(r)
    return [by[k].pop(0) for k in keys]


def _fly(scene, y0, ticks, rng: random.Random | None) -> TickFeeder:
    f = _feeder(scene, y0)
    for t, rs in ticks:
        order = rs if rng is None else _interleave(rs, rng)
        for i, r in enumerate(order):
            assert not f.ready(t), f"tick {t} ns ready with {i} of its {len(rs)} readings in"
            f.add(r)
        assert f.ready(t), f"tick {t} ns not ready with all its readings in"
        f.advance(t)
    return f


def test_a_tick_is_ready_exactly_when_its_last_reading_is_in_and_the_estimate_is_the_same_bits_in_any_order(flight):
    scene, y0, ticks = flight
    ref = _fly(scene, y0, ticks, None)
    for seed in (1, 2, 3):
        other = _fly(scene, y0, ticks, random.Random(seed))
        a, b = ref.filter.state, other.filter.state
        for name in ("r_W", "v_W", "q", "b_g", "b_a", "P"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    # from 10 km the radar sensors are out of range: their due samples are all "no readings"
    assert ref.dropouts["altimeter"] == sum(r.key == "altimeter" for _, rs in ticks for r in rs) > 0
    assert ref.unexpected == ref.unused == ref.rejected == 0
    assert ref.updates == sum(r.key == "star_tracker" for _, rs in ticks for r in rs)


def test_the_filter_fed_by_ticks_tracks_the_truth_within_its_covariance(flight):
    """Over 3 s the estimate's position error stays inside 4 sigma of the filter's own covariance."""
    scene, y0, ticks = flight
    f = _fly(scene, y0, ticks, None)
    sim = Simulation(scene)
    sim.step(TICKS * STEPS_PER_TICK)
    err = sim.y[0:3] - f.filter.state.r_W
    sd = np.sqrt(np.diag(f.filter.state.P)[0:3])
    assert np.all(np.abs(err) < 4.0 * sd), (err, sd)


def test_the_suite_samples_by_its_schedule():
    scene = load_scene("landing-sensors")
    a, b = SensorSuite(scene.sensors), SensorSuite(scene.sensors)
    sched = SampleSchedule({k: float(v["rate"]) for k, v in scene.sensors.sections.items()})
    sim = Simulation(scene)
    for _ in range(60):
        y, t = sim.y.copy(), sim.t
        sim.step()
        truth = truth_after_step(sim, y, sim.t - t)
        due = a.sample_due(truth)
        assert [k for k, _ in due] == sched.due(truth.t)
        got = b.sample(truth)
        assert [(m.key, m.z.tolist()) for m in got] == [(k, m.z.tolist()) for k, m in due if m is not None]


def test_a_tick_ending_on_a_step_without_the_imu_is_ready_without_it(flight):
    """A touchdown ends the last step inside the IMU's period: the tick's stamp is then no IMU
    instant, and the tick is ready with the IMU readings before it (and the other sensors due at it)."""
    scene, y0, ticks = flight
    f = _feeder(scene, y0)
    for r in ticks[0][1]:
        f.add(r)
    f.advance(0)
    first = ticks[1][1]
    f.add(first[0])  # the IMU at the first step, 0.01 s
    t_touch = first[0].t_ns + 4_000_000  # 4 ms later, before the IMU's next instant
    assert f.ready(t_touch)
    f.advance(t_touch)
    assert f.t_ns == first[0].t_ns and f.unexpected == 0


def test_a_reset_keeps_the_new_flights_first_readings_that_came_before_its_first_state(flight):
    """The simulator publishes a reset's readings at t = 0 before its state 1: the readings of the old
    flight still buffered are dropped, the new flight's kept, and its tick 0 is ready after the restart."""
    scene, y0, ticks = flight
    f = _feeder(scene, y0)
    for t, rs in ticks[:5]:
        for r in rs:
            f.add(r)
        f.advance(t)
    for r in ticks[5][1][:3]:  # part of a tick of the old flight, never completed
        f.add(r)
    for r in ticks[0][1]:  # the new flight's t = 0 readings, then its state 1
        f.add(r)
    f.restart()
    g = scene.models.get("gravity")
    f.start(start_filter(scene.sensors, y0[0:3], y0[3:6], y0[6:10], 0.0, initial_covariance(scene.sensors),
                         initial_error_rng(scene.sensors.seed), float(g.gm), float(g.radius)))
    assert f.ready(0)
    f.advance(0)
    assert all(not q for q in f.queues.values()) and f.unexpected == 0
    ref = _feeder(scene, y0)
    for r in ticks[0][1]:
        ref.add(r)
    ref.advance(0)
    assert np.array_equal(f.filter.state.P, ref.filter.state.P)
    assert np.array_equal(f.filter.state.q, ref.filter.state.q)


def test_a_stale_reading_is_dropped_and_counted_and_changes_nothing(flight):
    """A reading stamped before its sensor's last (a stranger's, a replay) is no step of the flight."""
    scene, y0, ticks = flight
    ref = _fly(scene, y0, ticks[:20], None)
    f = _feeder(scene, y0)
    stale = [r for r in ticks[3][1] if r.key == "imu"][0]
    for k, (t, rs) in enumerate(ticks[:20]):
        for r in rs:
            f.add(r)
        if k == 10:
            f.add(stale)
        f.advance(t)
    assert f.unexpected == 1
    assert np.array_equal(f.filter.state.P, ref.filter.state.P)
    assert np.array_equal(f.filter.state.r_W, ref.filter.state.r_W)
