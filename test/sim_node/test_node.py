"""Acceptance tests of the simulation node, over the real middleware (one node subprocess per module).

The probe in this process is a second node with ``use_sim_time``; it publishes
throttles and wind, calls the services and reads state, /clock, events and diagnostics.
"""
from __future__ import annotations

import itertools
import math
import time
from typing import Any

import numpy as np
import pytest

try:
    import rclpy  # noqa: F401
except ImportError as exc:  # fail loudly, never skip: these tests need the project venv
    raise ImportError("the node tests need ROS 2 from the project venv: run ./dev test test/sim_node") from exc

from std_srvs.srv import SetBool

from lander_interfaces.msg import FlightEvent
from lander_interfaces.srv import LoadScene, Reset, RunUntil, StepSimulation
from lander_sim.physics import constants as c
from lander_sim.ros.pacing import Pacer
from lander_sim.scenes import load_scene

from .probe import Probe, sim_node, state_fields, state_ns

pytestmark = pytest.mark.usefixtures("ros")


@pytest.fixture(scope="module")
def probe(ros, scenes, tmp_path_factory):
    log = tmp_path_factory.mktemp("sim_node") / "sim_node.log"
    params = {
        "scene": str(scenes["vertical"]),
        "start_paused": True,
        "speed": 0.0,
        "command_timeout": 0.0,
        "diagnostics_rate": 20.0,
    }
    with sim_node(params, log) as proc:
        p = Probe()
        try:
            p.wait_connected()
            p.proc = proc
            yield p
        finally:
            p.close()
        assert proc.poll() is None, f"the sim node died during the tests; log:\n{log.read_text()}"


def _load(probe: Probe, path) -> None:
    """Load a scene, paused, free-running, holding commands forever: a known starting point."""
    probe.call("pause")
    res = probe.call("load_scene", LoadScene.Request(scene=str(path)))
    assert res.success, res.message
    probe.answer = None
    probe.set_params(lockstep=False, speed=0.0, command_timeout=0.0)


def _diag_when_paused(probe: Probe) -> dict[str, str]:
    """A diagnostics report made after the pause (so it includes everything before it)."""
    probe.wait_for(lambda: bool(probe.diagnostics) and probe.diagnostics[-1]["paused"] == "True", 10.0, "a paused report")
    n = len(probe.diagnostics)
    return probe.diag_after(n)


def _paused_state(probe: Probe):
    """Pause, then the state at the pause instant (waiting out states still in flight)."""
    probe.call("pause")
    t_end = round(float(_diag_when_paused(probe)["sim_time"]) * 1e9)
    probe.wait_for(lambda: state_ns(probe.states[-1]) == t_end, 10.0, "the state at the pause")
    return probe.states[-1]


def _accepted_after(probe: Probe, action) -> None:
    """Do ``action`` (publishing commands) and wait until the node has accepted one more command.

    Topics and services are separate channels, and pausing publishes nothing new (one state per
    instant), so the node's own count in the diagnostics says when the command is in force.
    """
    n0 = int(probe.diag_after(len(probe.diagnostics))["commands_accepted"])
    action()
    probe.wait_for(lambda: int(probe.diagnostics[-1]["commands_accepted"]) > n0, 10.0, "the command to be accepted")


def _run_lockstep(probe: Probe, throttles: list[float], sim_seconds: float) -> list:
    """Fly in lockstep, answering every state with ``throttles``, for ``sim_seconds``; return the states."""
    probe.set_params(lockstep=True, speed=0.0)
    probe.answer = lambda state: throttles
    first = len(probe.states)
    probe.call("resume")
    probe.wait_for(lambda: len(probe.states) > first, 10.0, "the first state after resume")
    t0 = state_ns(probe.states[first])
    probe.wait_for(
        lambda: state_ns(probe.states[-1]) - t0 >= sim_seconds * 1e9, 60.0, f"{sim_seconds} s of lockstep flight"
    )
    probe.call("pause")
    probe.answer = None
    probe.set_params(lockstep=False)
    return list(probe.states)[first:]


def test_full_throttle_makes_a_hovering_lander_climb(probe, scenes):
    _load(probe, scenes["vertical"])
    scene = load_scene(str(scenes["vertical"]))
    states = _run_lockstep(probe, [1.0, 1.0, 1.0, 1.0], sim_seconds=2.0)
    burning = [s for s in states if list(s.throttles) == [1.0] * 4]
    assert len(burning) > 50, "the command was not applied in lockstep"
    a, b = burning[0], burning[-1]
    dt = (state_ns(b) - state_ns(a)) * 1e-9
    assert b.climb_rate > a.climb_rate + 1.0, "full throttle must make the lander climb"
    assert b.altitude > a.altitude
    # Vertical flight on the radial axis: d(climb)/dt = 4 T/m - GM/r^2. Mass falls and r changes
    # monotonically over the window, so the mean acceleration lies between the values at its two
    # ends; Verlet's velocity update is a trapezoid of accelerations inside that range.
    # The 1e-9 relative slack is float rounding only.
    T = sum(t.max_thrust for t in scene.vehicle.thrusters)
    r = [c.MARS_RADIUS + s.altitude for s in (a, b)]
    acc = [T / s.mass - c.GM_MARS / rr**2 for s, rr in zip((a, b), r)]
    mean = (b.climb_rate - a.climb_rate) / dt
    lo, hi = min(acc), max(acc)
    assert lo * (1 - 1e-9) <= mean <= hi * (1 + 1e-9), (lo, mean, hi)
    assert a.mass > b.mass, "burning fuel must reduce the mass"


def test_one_canted_thruster_spins_the_lander_the_way_its_torque_points(probe, scenes):
    _load(probe, scenes["canted"])
    vehicle = load_scene(str(scenes["canted"])).vehicle
    throttle = 0.2
    states = _run_lockstep(probe, [throttle, 0.0, 0.0, 0.0], sim_seconds=0.2)
    # Expected sign from the geometry: F = -d T t, torque = p x F = -t T (p x d) = -t T s_0 (body);
    # from rest Euler's equations (eq 2) give omega_dot = I^-1 torque to first order in t
    # (the gyroscopic term I omega x omega is second order), so omega_B has the sign of I^-1 torque.
    s0 = vehicle.torque_arms()[0]
    torque_B = -throttle * vehicle.thrusters[0].max_thrust * s0
    alpha = torque_B / vehicle.inertia(vehicle.fuel_capacity)
    last = states[-1]
    omega = np.array([last.angular_velocity.x, last.angular_velocity.y, last.angular_velocity.z])
    assert np.all(np.abs(alpha) > 0.05 * np.max(np.abs(alpha))), "the test needs every axis to be driven"
    assert np.array_equal(np.sign(omega), np.sign(alpha)), (omega, alpha)


@pytest.mark.parametrize("speed, wall_window", [(1.0, 1.5), (20.0, 1.0)])
def test_a_sim_time_node_follows_the_simulation_clock_exactly(probe, scenes, speed, wall_window):
    _load(probe, scenes["vertical"])
    probe.set_params(speed=speed)
    d0 = _diag_when_paused(probe)
    t_start = float(d0["sim_time"])
    first = len(probe.states)
    a0 = time.monotonic()
    probe.call("resume")
    a1 = time.monotonic()
    probe.wait_for(lambda: len(probe.states) > first + 2, 10.0, "states after resume")
    probe.spin_for(wall_window)
    b0 = time.monotonic()
    probe.call("pause")
    b1 = time.monotonic()
    d1 = _diag_when_paused(probe)
    t_end = round(float(d1["sim_time"]) * 1e9)
    # Exact: once paused, the probe's sim-time clock reads exactly the node's final sim time.
    probe.wait_for(lambda: probe.node.get_clock().now().nanoseconds == t_end, 10.0, "the probe clock to reach the sim time")
    probe.wait_for(lambda: state_ns(probe.states[-1]) == t_end, 10.0, "the state published at the pause")
    stamps = {state_ns(s) for s in probe.states}
    seen = [clk for _, clk in list(probe.clock_seen_at_state)[first:]]
    # The probe's clock only ever shows instants the simulation published, and never goes back.
    assert set(seen) <= stamps
    assert all(b >= a for a, b in zip(seen, seen[1:]))
    # Rate, bracketed by the service calls' round trips (measured here, so a probe starved of CPU
    # widens the bracket instead of failing the test): the node ran from its resume, answered in
    # [a0, a1], to its pause, answered in [b0, b1]. The schedule is absolute and starts one control
    # period after the resume, and no tick ends before it is due (a re-anchoring only moves later
    # ticks later), so sim time never runs ahead: d_sim <= speed (b1 - a0). Behind: the pacer counts
    # an overrun whenever the loop is more than max_lag behind, at a tick or at the pause, so with
    # none the tick after the last one was due no earlier than the pause minus max_lag:
    # d_sim >= speed (b0 - a1 - max_lag) - one period. A machine too loaded to keep up must say so
    # (pacer_overruns in the diagnostics). 1e-9 s: float rounding of the stamps.
    d_sim = t_end * 1e-9 - t_start
    period = float(d1["steps_per_tick"]) * load_scene(str(scenes["vertical"])).dt
    assert d_sim <= speed * (b1 - a0) + 1e-9, (d_sim, speed * (b1 - a0))
    overruns = int(d1["pacer_overruns"]) - int(d0["pacer_overruns"])
    if speed <= 1.0:
        assert overruns == 0, "real time must be kept on any machine"
    if overruns == 0:
        max_lag = Pacer(speed, period).max_lag
        assert d_sim >= speed * (b0 - a1 - max_lag) - period - 1e-9, (d_sim, speed * (b0 - a1))
    else:
        print(f"speed {speed}: fell behind ({d_sim:.2f} s sim in {b0 - a1:.2f}-{b1 - a0:.2f} s wall) and reported {overruns} overruns")


def test_step_advances_exactly_n_dt_and_reset_restores_the_initial_state_bit_for_bit(probe, scenes):
    _load(probe, scenes["vertical"])
    dt = load_scene(str(scenes["vertical"])).dt
    s0 = probe.latest_state_after(lambda: probe.call("reset", Reset.Request()))
    assert state_ns(s0) == 0 and s0.sequence == 1
    res = probe.call("step", StepSimulation.Request(steps=100))
    assert res.success, res.message
    # The core counts whole steps (t = k dt), so 100 steps from t = 0 is exactly 100 * dt in floats,
    # and the stamp is that time rounded to the nanosecond.
    assert res.sim_time == 100 * dt
    # The states travel on a topic, not with the response: wait for the one the step ended on.
    probe.wait_for(lambda: state_ns(probe.states[-1]) == round(100 * dt * 1e9), 10.0, "the state stamped 100 dt")
    after = probe.states[-1]
    assert after.position.z != s0.position.z, "gravity must have moved the lander"
    # Now disturb everything the node holds: throttles, wind, stabiliser, more steps.
    probe.send_wind(5.0, -2.0, 1.0)
    _accepted_after(probe, lambda: probe.send_throttles([0.3, 0.6, 0.1, 0.9]))
    probe.call("set_stabiliser", SetBool.Request(data=True))
    res = probe.call("step", StepSimulation.Request(steps=37))
    assert res.success and res.sim_time == 137 * dt
    probe.wait_for(lambda: state_ns(probe.states[-1]) == round(137 * dt * 1e9), 10.0, "the state stamped 137 dt")
    moved = probe.states[-1]
    assert list(moved.throttles) == [0.3, 0.6, 0.1, 0.9]
    s1 = probe.latest_state_after(lambda: probe.call("reset", Reset.Request(use_seed=True, seed=7)))
    assert state_fields(s1) == state_fields(s0)
    assert s1.sequence == 1


def test_the_reports_carry_the_mean_wind_in_force_and_a_reset_restores_the_scenes(probe, scenes):
    """``mean_wind_W`` (x y z, m/s, world frame) in the diagnostics: what a live view shows as the
    wind in force, whoever set it. A refused wind leaves it; a reset restores the scene's."""
    _load(probe, scenes["vertical"])
    scene_wind = " ".join(repr(float(v)) for v in load_scene(str(scenes["vertical"])).wind_W)
    n = len(probe.diagnostics)
    probe.send_wind(5.0, -2.0, 1.0)
    probe.wait_for(lambda: any(d.get("mean_wind_W") == "5.0 -2.0 1.0" for d in probe.diagnostics[n:]), 10.0,
                   "a report of the wind set")
    probe.send_wind(math.nan, 0.0, 0.0)  # refused: the wind in force stays
    probe.wait_for(lambda: int(probe.diagnostics[-1].get("rejected.wind.non_finite", "0")) >= 1, 10.0, "the refusal")
    assert probe.diag_after(len(probe.diagnostics))["mean_wind_W"] == "5.0 -2.0 1.0"
    probe.call("reset", Reset.Request())
    probe.wait_for(lambda: probe.diagnostics[-1].get("mean_wind_W") == scene_wind, 10.0, "the scene's wind after the reset")


def test_each_reset_begins_the_next_flight_number_in_the_pause_answer_and_the_reports(probe, scenes):
    """The flight number tells a report of the old flight from one of the new (lander record
    --whole-flight drops the old flight's reports sent across its reset)."""
    from lander_ros.flight_span import paused_flight

    _load(probe, scenes["vertical"])
    before = paused_flight(probe.call("pause").message)
    assert before is not None
    assert _diag_when_paused(probe)["flight"] == str(before)
    probe.call("reset", Reset.Request())
    after = probe.call("pause")
    assert paused_flight(after.message) == before + 1 and "(was paused), flight " in after.message, after.message
    probe.wait_for(lambda: probe.diagnostics[-1]["flight"] == str(before + 1), 10.0, "a report of the new flight")
    assert paused_flight("paused at t = 1.5 s (was running)") is None  # a sim from before the numbers


def test_services_refuse_bad_arguments_and_count_them(probe, scenes):
    _load(probe, scenes["vertical"])
    before = _paused_state(probe)
    n = len(probe.diagnostics)
    d0 = probe.diag_after(n)
    res = probe.call("load_scene", LoadScene.Request(scene="no-such-scene"))
    assert not res.success and "no-such-scene" in res.message
    res = probe.call("step", StepSimulation.Request(steps=0))
    assert not res.success and "steps" in res.message
    res = probe.call("run_until", RunUntil.Request(sim_time=math.nan))
    assert not res.success and "sim_time" in res.message
    res = probe.call("run_until", RunUntil.Request(sim_time=-1.0))
    assert not res.success
    refused = probe.set_params_result(speed=-1.0)
    assert not refused[0].successful and "speed" in refused[0].reason
    expected = [("service.load_scene", 1), ("service.step", 1), ("service.run_until", 2)]
    diff = lambda d, k: int(d.get(f"rejected.{k}", 0)) - int(d0.get(f"rejected.{k}", 0))  # noqa: E731
    probe.wait_for(
        lambda: all(diff(probe.diagnostics[-1], k) >= n for k, n in expected), 10.0, "diagnostics with the refusals"
    )
    d1 = probe.diagnostics[-1]
    for key, count in expected:
        assert int(d1.get(f"rejected.{key}", 0)) - int(d0.get(f"rejected.{key}", 0)) == count, key
    after = _paused_state(probe)
    assert state_fields(after) == state_fields(before)


def test_run_until_reaches_the_requested_time_on_the_step_grid(probe, scenes):
    _load(probe, scenes["vertical"])
    dt = load_scene(str(scenes["vertical"])).dt
    probe.call("reset", Reset.Request())
    res = probe.call("run_until", RunUntil.Request(sim_time=1.234))
    assert res.success, res.message
    # Whole steps, the last reaching or passing the target: within one dt at or after it.
    assert 1.234 <= res.sim_time_reached + 1e-12 and res.sim_time_reached < 1.234 + dt
    expected = round(res.sim_time_reached * 1e9)
    probe.wait_for(lambda: state_ns(probe.states[-1]) == expected, 10.0, "the state stamped at the reached time")


_MALFORMED = {
    "throttle.nan": lambda i: ("t", [math.nan, 0.0, 0.0, 0.0] if i % 2 else [0.5, 0.5, 0.5, math.nan]),
    "throttle.inf": lambda i: ("t", [math.inf, 0.0, 0.0, 0.0] if i % 2 else [0.0, 0.0, -math.inf, 0.0]),
    "throttle.out_of_range": lambda i: ("t", [1.5, 0.0, 0.0, 0.0] if i % 2 else [0.0, -0.25, 0.0, 0.0]),
    "throttle.wrong_length": lambda i: ("t", [0.5] * (3 if i % 2 else 5)),
    "wind.non_finite": lambda i: ("w", [math.nan, 0.0, 0.0] if i % 2 else [0.0, math.inf, 0.0]),
}


def test_a_thousand_malformed_messages_of_each_kind_are_counted_and_change_nothing(probe, scenes):
    _load(probe, scenes["vertical"])
    probe.call("step", StepSimulation.Request(steps=10))  # not the initial state: a moving lander
    before = _paused_state(probe)
    d0 = probe.diag_after(len(probe.diagnostics))
    rejected = lambda: sum(1 for e in probe.events if e.kind == FlightEvent.INPUT_REJECTED)  # noqa: E731
    for kind, make in _MALFORMED.items():
        for chunk in range(10):
            # Chunks of 100 (the node's input queue holds 200) so none is dropped before it is counted.
            n0 = rejected()
            for i in range(100):
                topic, values = make(i)
                if topic == "t":
                    probe.send_throttles(values)
                else:
                    probe.send_wind(*values)
            probe.wait_for(lambda: rejected() >= n0 + 100, 30.0, f"100 rejections of {kind} (chunk {chunk})")
    assert probe.proc.poll() is None, "the node must stay up"
    # Diagnostics and events are separate topics: wait for a report that includes the last chunk.
    count = lambda d, k: int(d.get(f"rejected.{k}", 0)) - int(d0.get(f"rejected.{k}", 0))  # noqa: E731
    probe.wait_for(
        lambda: bool(probe.diagnostics) and all(count(probe.diagnostics[-1], k) >= 1000 for k in _MALFORMED),
        10.0,
        "diagnostics counting every rejection",
    )
    d1 = probe.diagnostics[-1]
    for kind in _MALFORMED:
        assert int(d1[f"rejected.{kind}"]) - int(d0.get(f"rejected.{kind}", 0)) == 1000, kind
    after = _paused_state(probe)
    assert state_fields(after) == state_fields(before)


def test_a_held_command_goes_stale_after_the_limit_and_throttles_drop_to_zero(probe, scenes):
    _load(probe, scenes["vertical"])
    limit, period = 0.1, 1.0 / 50.0
    probe.set_params(command_timeout=limit)
    _accepted_after(probe, lambda: probe.send_throttles([1.0, 1.0, 1.0, 1.0]))
    t_cmd = float(probe.diagnostics[-1]["sim_time"])  # paused: the command was accepted at this sim time
    n_events = len(probe.events)
    probe.call("resume")
    stale = lambda: [e for e in probe.events[n_events:] if e.kind == FlightEvent.COMMAND_STALE]  # noqa: E731
    probe.wait_for(lambda: bool(stale()), 10.0, "a COMMAND_STALE event")
    probe.call("pause")
    probe.set_params(command_timeout=0.0)
    t_stale = state_ns(stale()[0]) * 1e-9  # the event is stamped with the sim time it was detected
    # Checked once per control tick: the first tick that starts more than `limit` after the command.
    assert limit < t_stale - t_cmd <= limit + period + 1e-9
    probe.wait_for(lambda: list(probe.states[-1].throttles) == [0.0] * 4, 10.0, "zero throttles after staleness")


def test_a_users_step_flies_the_held_command_and_does_not_age_it(probe, scenes):
    """Paused, a command set, then a step far longer than the staleness limit: every stepped state
    flies the command (nobody can answer inside the step), and once the flight runs on its own the
    command goes stale `limit` after it was accepted, the stepped time not counted."""
    _load(probe, scenes["vertical"])
    limit, period, steps = 0.1, 1.0 / 50.0, 25  # the step: 0.5 s of sim time, five limits
    dt = load_scene(str(scenes["vertical"])).dt
    probe.set_params(command_timeout=limit)
    _accepted_after(probe, lambda: probe.send_throttles([1.0, 1.0, 1.0, 1.0]))
    n_events = len(probe.events)
    res = probe.call("step", StepSimulation.Request(steps=steps))
    assert res.success, res.message
    t_end = res.sim_time  # the step's start is `steps` dt before (the paused instant the command came at)
    probe.wait_for(lambda: state_ns(probe.states[-1]) == round(t_end * 1e9), 10.0, "the step's last state")
    # The states of the step's ticks, after its start instant (half a step clear of float rounding).
    after_start_ns = round((t_end - (steps - 0.5) * dt) * 1e9)
    # The last states published (paused after the step): back from the end to the step's start.
    stepped = list(itertools.takewhile(lambda m: state_ns(m) > after_start_ns, reversed(probe.states)))
    assert stepped and all(list(s.throttles) == [1.0] * 4 for s in stepped), [list(s.throttles) for s in stepped]
    stale = lambda: [e for e in probe.events[n_events:] if e.kind == FlightEvent.COMMAND_STALE]  # noqa: E731
    assert not stale()
    probe.call("resume")
    probe.wait_for(lambda: bool(stale()), 10.0, "a COMMAND_STALE event once running")
    probe.call("pause")
    probe.set_params(command_timeout=0.0)
    t_stale = state_ns(stale()[0]) * 1e-9
    assert limit < t_stale - t_end <= limit + period + 1e-9


def test_lockstep_waits_for_the_answer_and_counts_a_timeout(probe, scenes):
    _load(probe, scenes["vertical"])
    probe.set_params(lockstep=True, lockstep_timeout=0.3, speed=0.0)
    d0 = probe.diag_after(len(probe.diagnostics))
    first = len(probe.states)
    probe.call("resume")  # publishes a state nobody answers
    w0 = time.monotonic()
    probe.wait_for(lambda: len(probe.states) >= first + 2, 10.0, "the state after a lockstep timeout")
    waited = time.monotonic() - w0
    probe.call("pause")
    probe.set_params(lockstep=False)
    # Unanswered, the sim advanced only after lockstep_timeout of wall time (minus nothing: the
    # wait starts when the state is published, before our service call returned).
    assert waited >= 0.3 - 0.05  # 50 ms: the resume call's own round trip happens inside the wait
    d1 = _diag_when_paused(probe)
    assert int(d1["lockstep_timeouts"]) > int(d0["lockstep_timeouts"])


def test_one_state_per_instant_sequences_and_stamps_strictly_increase_within_a_reset(probe, scenes):
    """Reset publishes state 1 at t = 0; pause and resume publish nothing; step and running add one
    state per new instant. So within a reset epoch (sequence, stamp) pairs never repeat and both
    strictly increase: a (sequence -> sim time) map is well defined for latency and lockstep."""
    _load(probe, scenes["vertical"])
    first = len(probe.states)
    s0 = probe.latest_state_after(lambda: probe.call("reset", Reset.Request()))
    assert (s0.sequence, state_ns(s0)) == (1, 0)
    probe.call("step", StepSimulation.Request(steps=3))
    probe.call("pause")
    probe.call("resume")
    probe.wait_for(lambda: state_ns(probe.states[-1]) >= 0.5e9, 10.0, "0.5 s of flight")
    probe.call("pause")
    probe.call("resume")
    probe.call("pause")
    last = _paused_state(probe)
    epoch = [s for s in list(probe.states)[first:] if s is s0 or s.sequence > 0]
    epoch = epoch[[i for i, s in enumerate(epoch) if s.sequence == 1][-1]:]
    seqs = [s.sequence for s in epoch]
    stamps = [state_ns(s) for s in epoch]
    assert seqs == list(range(1, last.sequence + 1)), "a state is missing or repeated"
    assert all(b > a for a, b in zip(stamps, stamps[1:])), "two states share a sim time"


def test_pause_at_speed_0_in_lockstep_takes_effect_within_a_control_period(probe, scenes):
    """In lockstep the sim is never more than one control period ahead of its controller (this
    probe), so the time the probe last saw is the sim's to within one period. The pause must stop
    the sim at most one period after that (the tick in progress may finish), i.e. requests are
    served between control periods even when running as fast as possible. Repeated at several
    instants; period 0.02 s (50 Hz over dt = 0.01: two physics steps per tick)."""
    _load(probe, scenes["vertical"])
    probe.set_params(lockstep=True, speed=0.0, lockstep_timeout=5.0)
    period = 0.02
    probe.answer = lambda state: [0.25] * 4
    probe.call("reset", Reset.Request())
    for _ in range(5):
        probe.call("resume")
        n0 = len(probe.states)
        probe.wait_for(lambda: len(probe.states) > n0 + 50, 30.0, "50 lockstep periods")
        seen = state_ns(probe.states[-1]) * 1e-9
        probe.call("pause")
        t_paused = float(_diag_when_paused(probe)["sim_time"])
        assert seen - 1e-9 <= t_paused <= seen + 2 * period + 1e-9, (seen, t_paused)
    probe.answer = None
    probe.set_params(lockstep=False, lockstep_timeout=1.0)


def test_control_loop_latency_is_reported_from_the_answers_sequence_numbers(probe, scenes):
    """Every answered state gives one sample: state published -> command with its sequence accepted.
    The probe answers from its callback, so the latency is positive and well under the lockstep
    timeout (no timeout was counted); p50 <= p95 by definition."""
    _load(probe, scenes["vertical"])
    probe.set_params(lockstep=True, speed=0.0, lockstep_timeout=5.0)
    d0 = probe.diag_after(len(probe.diagnostics))
    probe.answer = lambda state: [0.25] * 4
    probe.call("reset", Reset.Request())
    probe.call("resume")
    probe.wait_for(lambda: state_ns(probe.states[-1]) >= 2e9, 30.0, "2 s of lockstep flight")
    probe.call("pause")
    probe.answer = None
    d1 = _diag_when_paused(probe)
    probe.set_params(lockstep=False, lockstep_timeout=1.0)
    assert int(d1["lockstep_timeouts"]) == int(d0["lockstep_timeouts"])
    assert int(d1["control_latency_samples"]) >= 100  # >= 2 s at 50 Hz, every state answered
    p50, p95 = float(d1["control_latency_p50_ms"]), float(d1["control_latency_p95_ms"])
    assert 0.0 < p50 <= p95 < 5000.0, (p50, p95)


def test_the_flight_ends_by_itself_at_end_time_with_the_counts_of_what_it_published(probe, scenes):
    """end_time: the node publishes the end instant's state, then FLIGHT_ENDED with its counts since
    the reset, then nothing; resume is refused until a reset (docs/sim_node.md, "A flight's span")."""
    from std_srvs.srv import Trigger

    from lander_ros.flight_span import FlightEnd, parse_matched

    _load(probe, scenes["vertical"])
    probe.wait_for(lambda: bool(probe.clocks) and probe.clocks[-1] == 0, 10.0, "the load's clock")  # not counted below
    cli = probe.node.create_client(Trigger, "/lander/subscribers")
    assert cli.wait_for_service(timeout_sec=30.0)
    fut = cli.call_async(Trigger.Request())
    probe.wait_for(fut.done, 30.0, "/lander/subscribers")
    matched = parse_matched(fut.result().message)
    # This probe listens to the state and clock and publishes throttles and wind: matched both ways.
    assert matched["/lander/state"] >= 1 and matched["/clock"] >= 1, matched
    assert matched["sub:/lander/throttle"] >= 1 and matched["sub:/lander/wind"] >= 1, matched

    end_time = 1.05
    probe.set_params(end_time=end_time)
    try:
        n_states, n_clocks, n_events = len(probe.states), len(probe.clocks), len(probe.events)
        assert probe.call("reset").success
        assert probe.call("resume").success
        def ended() -> list[Any]:
            return [e for e in probe.events[n_events:] if e.kind == FlightEvent.FLIGHT_ENDED]

        probe.wait_for(lambda: bool(ended()), 30.0, "FLIGHT_ENDED")
        end = FlightEnd.from_values(list(ended()[0].values))
        probe.wait_for(lambda: len(probe.states) - n_states >= end.counts["/lander/state"]
                       and len(probe.clocks) - n_clocks >= end.counts["/clock"], 10.0, "every state and clock")
        states = list(probe.states)[n_states:]
        assert [s.sequence for s in states] == list(range(1, len(states) + 1))
        assert len(states) == end.counts["/lander/state"] and len(probe.clocks) - n_clocks == end.counts["/clock"]
        period = (state_ns(states[-1]) - state_ns(states[-2])) * 1e-9
        # The end instant: the first control instant at or after end_time, and it is the last state.
        assert state_ns(states[-1]) == round(end.t * 1e9) and end.t - period < end_time <= end.t + 1e-9
        assert end.reason == "time-limit"
        refused = probe.call("resume")
        assert not refused.success and "ended" in refused.message
        probe.spin_for(0.3)
        assert len(probe.states) - n_states == end.counts["/lander/state"], "a state after the end"
    finally:
        probe.set_params(end_time=-1.0)
        _load(probe, scenes["vertical"])
