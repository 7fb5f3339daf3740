"""Metrics of lander_tools.analysis against closed forms of second-order step responses
(control reference eq 19-21) and of torque-free spin, on synthetic bags; plots and comparisons."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from lander_sim.physics import state as S
from lander_sim.physics.rotation import axis_angle_to_quat, euler_to_matrix
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.analysis import Flight, metrics, table, to_json
from lander_tools.analysis_plots import canonical_zxz, figures, write_plots
from lander_tools.bagio import read_bag
from lander_tools.metrics_fit import GIMBAL_LOCK_KIND

from .synth import write_flight_bag

DT = 0.01  # sample period of the synthetic flights [s]


def _second_order(t: np.ndarray, e0: float, p1: float, p2: float) -> tuple[np.ndarray, np.ndarray]:
    """Error e(t) and its rate for e'' = -(p1 p2) e + (p1 + p2) e', e(0) = e0, e'(0) = 0 (real poles)."""
    e = e0 * (p2 * np.exp(p1 * t) - p1 * np.exp(p2 * t)) / (p2 - p1)
    de = e0 * p1 * p2 * (np.exp(p1 * t) - np.exp(p2 * t)) / (p2 - p1)
    return e, de


def test_overdamped_step_settling_time_matches_the_closed_form(tmp_path: Path) -> None:
    # Seed 2's altitude poles -0.9 and -1.1: a 10 m step from 500 m to 510 m starting at t = 5 s.
    t = np.arange(0, 30, DT)
    tau = np.clip(t - 5.0, 0.0, None)
    e, de = _second_order(tau, -10.0, -0.9, -1.1)
    h = 510.0 + e
    h[t < 5.0] = 500.0
    write_flight_bag(tmp_path / "b", t, h, de, demand=[(0.0, 500.0), (5.0, 510.0)])
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")), band_min=0.0)
    # Closed form: |e| falls monotonically (overdamped), so the 2 % time is the root of |e| = 0.2 m.
    ts = brentq(lambda x: abs(_second_order(np.array([x]), -10.0, -0.9, -1.1)[0][0]) - 0.2, 0.1, 30.0)
    assert m.step_size == pytest.approx(10.0, abs=1e-9)
    # Sampled at DT: the first sample inside the band is at most one period after the crossing.
    assert ts <= m.settling_time <= ts + DT + 1e-9
    assert m.overshoot_percent == 0.0  # overdamped: never past the demand
    # 25 s after the step the error is 10 m * O(e^{-0.9 * 20}) < 1e-6 m over the last 20 %.
    assert abs(m.steady_state_error) < 1e-6


def test_underdamped_overshoot_matches_exp_of_minus_pi_zeta(tmp_path: Path) -> None:
    zeta, wn = 0.5, 1.0
    wd = wn * math.sqrt(1 - zeta**2)
    t = np.arange(0, 40, DT)
    # Unit-step response of wn^2 / (s^2 + 2 zeta wn s + wn^2), scaled to a 20 m step down.
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))
    dy = wn / math.sqrt(1 - zeta**2) * np.exp(-zeta * wn * t) * np.sin(wd * t)
    write_flight_bag(tmp_path / "b", t, 500.0 - 20.0 * y, -20.0 * dy, demand=[(0.0, 480.0)])
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")), band_min=0.0)
    expected = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))  # 16.30 %
    # The sampled peak is within DT of the true peak at t = pi / wd, where the response is flat:
    # the error is O((wd DT)^2 / 2 * overshoot) ~ 1e-3 %.
    assert m.overshoot_percent == pytest.approx(expected, abs=0.01)
    # The envelope exp(-zeta wn t) * 20 m / sqrt(1 - zeta^2) reaches 2 % (0.4 m) at ~8.1 s; the
    # response settles at or before the envelope does.
    assert m.settling_time <= -math.log(0.02 * math.sqrt(1 - zeta**2)) / (zeta * wn) + DT


def test_constant_offset_is_the_steady_state_error(tmp_path: Path) -> None:
    t = np.arange(0, 20, DT)
    write_flight_bag(tmp_path / "b", t, np.full(len(t), 499.7), np.zeros(len(t)), demand=[(0.0, 500.0)])
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")))
    assert m.steady_state_error == pytest.approx(-0.3, abs=1e-9)
    assert m.settling_time == 0.0  # inside the 0.5 m band from the start


def test_steady_state_is_taken_after_settling_not_over_a_long_approach(tmp_path: Path) -> None:
    # A de-orbit's shape: 200 s falling 20 km at 100 m/s to the demand, then 20 s of hover 0.3 m
    # under it. The last 20 % of the segment (44 s) would average 24 s of the fall in; the steady
    # state is the hover's offset, and its largest error too.
    t = np.arange(0, 220, DT)
    h = np.where(t < 200.0, 20_500.0 - 100.0 * t, 499.7)
    write_flight_bag(tmp_path / "b", t, h, np.gradient(h, t), demand=[(0.0, 500.0)])
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")))
    # Band: 2 % of the 20 km step, 400 m, entered 4 s before the demand (the tail is all hover).
    assert m.settling_time == pytest.approx(196.0, abs=DT + 1e-9)
    assert m.steady_state_error == pytest.approx(-0.3, abs=1e-9)
    assert m.hover_error_max == pytest.approx(0.3, abs=1e-9)


def test_steady_state_is_the_hover_when_the_step_band_is_wider_than_the_braking(tmp_path: Path) -> None:
    # A fall of 20 km at 100 m/s into the 2 % band (400 m), a 40 s braking through it at 10 m/s, a
    # 5 s hover 0.3 m under the demand, then a landing demand. The band's settled part is 45 s and
    # its last 20 % (9 s) would hold 4 s of the braking (errors to 40 m); settled within band_min
    # (0.5 m), the tail is the hover's.
    t = np.arange(0, 260, DT)
    h = np.where(t < 196.0, 20_500.0 - 100.0 * t, np.where(t < 236.0, 900.0 - 10.0 * (t - 196.0), 499.7))
    h = np.where(t < 241.0, h, np.maximum(499.7 - 10.0 * (t - 241.0), 0.5))
    write_flight_bag(tmp_path / "b", t, h, np.gradient(h, t), demand=[(0.0, 500.0), (241.0, 0.0)],
                     phase=np.where(h <= 0.5, 1, 0))
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")))
    assert m.settling_time == pytest.approx(196.0, abs=DT + 1e-9)  # the 2 % band, as the sweeps define it
    assert m.steady_state_error == pytest.approx(-0.3, abs=1e-9)
    assert m.hover_error_max == pytest.approx(0.3, abs=1e-9)


def test_a_landing_on_demand_is_measured_on_the_hover_before_it_and_a_landing_alone_has_no_step(tmp_path: Path) -> None:
    # 50 s of hover 0.3 m under the 500 m demand, then the demand 0 m (land) and a descent at
    # 16.65 m/s to rest on the ground (the lander's centre 0.5 m over it) from 80 s on.
    t = np.arange(0, 90, DT)
    h = np.where(t < 50.0, 499.7, np.maximum(499.7 - 16.64 * (t - 50.0), 0.5))
    landed = np.where(h <= 0.5, 1, 0)
    t_down = t[np.argmax(landed)]
    write_flight_bag(tmp_path / "b", t, h, np.gradient(h, t), demand=[(0.0, 500.0), (50.0, 0.0)], phase=landed)
    m = metrics(Flight.from_bag(read_bag(tmp_path / "b")))
    assert m.outcome == "landed" and m.final_altitude == 0.5
    # the hover's step (the first demand) over its segment, to the landing demand: not the
    # landing's "step" to 0 m, whose tail is the lander resting 0.5 m over it
    assert m.demand_altitude == 500.0 and m.step_size == pytest.approx(0.3, abs=1e-9)
    assert m.steady_state_error == pytest.approx(-0.3, abs=1e-9) and m.hover_error_max == pytest.approx(0.3, abs=1e-9)
    # A landing from the start (the landing scenes' demand 0 m) has no step response at all.
    write_flight_bag(tmp_path / "l", t, h, np.gradient(h, t), demand=[(0.0, 0.0)], phase=landed)
    m = metrics(Flight.from_bag(read_bag(tmp_path / "l")))
    assert m.outcome == "landed"
    assert (m.demand_altitude, m.step_size, m.settling_time, m.overshoot_percent, m.steady_state_error,
            m.hover_error_max) == (None,) * 6
    # A hover that ends on the ground without a landing demand is measured to the touchdown: the
    # state after it (at rest 499.2 m under the demand) is not the step's.
    write_flight_bag(tmp_path / "c", t, h, np.gradient(h, t), demand=[(0.0, 500.0)], phase=landed)
    m = metrics(Flight.from_bag(read_bag(tmp_path / "c")))
    expect = h[(t <= t_down)] - 500.0
    assert m.demand_altitude == 500.0 and m.hover_error_max == pytest.approx(np.max(np.abs(expect[-int(len(expect) * 0.2):])), abs=1e-9)


def test_angular_momentum_drift_is_zero_for_a_true_free_spin_and_large_for_a_wrong_one(tmp_path: Path) -> None:
    # Spin about the body x axis (a principal axis): omega constant, q(t) = q_x(0.8 t) exactly,
    # so L_W = R^T I omega is constant (eq 2: omega x I omega = 0) up to rounding.
    t = np.arange(0, 10, 0.1)
    w = np.tile([0.8, 0.0, 0.0], (len(t), 1))
    q_ok = np.array([axis_angle_to_quat(np.array([1.0, 0, 0]), 0.8 * x) for x in t])
    q_bad = np.array([axis_angle_to_quat(np.array([0, 0, 1.0]), 0.8 * x) for x in t])
    zero = np.zeros((len(t), 4))
    h = np.full(len(t), 1e6)
    # Scenario 8's lander far from Mars: gravity alone, through the centre of mass (no torque).
    free = {"scene": "free-spin"}
    write_flight_bag(tmp_path / "ok", t, h, np.zeros(len(t)), omega_B=w, q=q_ok, throttles=zero, meta=free)
    write_flight_bag(tmp_path / "bad", t, h, np.zeros(len(t)), omega_B=w, q=q_bad, throttles=zero, meta=free)
    ok = metrics(Flight.from_bag(read_bag(tmp_path / "ok")))
    bad = metrics(Flight.from_bag(read_bag(tmp_path / "bad")))
    assert ok.angular_momentum_drift < 1e-12  # a few ulps of |L|
    # The inconsistent attitude turns L_W about z by up to 180 deg: drift up to |L - (-L)|/|L| = 2.
    assert bad.angular_momentum_drift > 1.0
    assert ok.quaternion_norm_drift < 1e-12 and ok.final_spin_rate == pytest.approx(0.8, abs=1e-15)


def test_plots_table_json_and_comparison(tmp_path: Path) -> None:
    t = np.arange(0, 20, 0.05)
    e, de = _second_order(t, 5.0, -0.9, -1.1)
    write_flight_bag(tmp_path / "a", t, 500.0 + e, de, demand=[(0.0, 500.0)])
    write_flight_bag(tmp_path / "rotor", t, 500.0 + 2 * e, 2 * de, demand=[(0.0, 500.0)], meta={"scene": "rotor-quaternion"})
    fa = Flight.from_bag(read_bag(tmp_path / "a"), name="a")
    fb = Flight.from_bag(read_bag(tmp_path / "rotor"), name="b")
    paths = write_plots([fa], tmp_path / "one")
    assert [p.name for p in paths] == [f"flight-{k}.png" for k in ("altitude", "attitude", "throttles", "trajectory")]
    paths2 = write_plots([fa, fb], tmp_path / "two", prefix="cmp")
    assert paths2[-1].name == "cmp-ztrack.png"  # rotor flights get the Figure 1 z-axis track
    for p in paths + paths2:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    write_flight_bag(tmp_path / "b", t, 500.0 + 2 * e, 2 * de, demand=[(0.0, 500.0)])
    ma, mb = metrics(fa), metrics(Flight.from_bag(read_bag(tmp_path / "b"), name="b"))
    doc = json.loads(to_json([ma, mb]))
    # The doubled error takes longer to reach the same 0.5 m band: the difference is positive.
    assert doc["differences"]["b"]["settling_time"] == pytest.approx(mb.settling_time - ma.settling_time)
    assert doc["differences"]["b"]["settling_time"] > 0
    text = table([ma, mb])
    assert "difference (2 - 1)" in text and "settling_time [s]" in text


def test_demand_in_force_comes_from_the_autopilot_status_and_is_timed_when_flown(tmp_path: Path) -> None:
    # The scene's demand is never published on /lander/demand_altitude; the status
    # carries it from the first state. A demand published at 5.00 s is flown from the next control
    # instant (5.02 s here), which is when the step starts for the controller.
    t = np.arange(0, 20, DT)
    tau = np.clip(t - 5.02, 0.0, None)
    e, de = _second_order(tau, -10.0, -0.9, -1.1)
    h = np.where(t < 5.02 - 1e-9, 500.0, 510.0 + e)
    status = np.where(t < 5.02 - 1e-9, 500.0, 510.0)
    write_flight_bag(tmp_path / "s", t, h, de, demand=[(5.0, 510.0)], status_demand=status)
    f = Flight.from_bag(read_bag(tmp_path / "s"))
    np.testing.assert_allclose(f.demand_t, [0.0, t[502]])
    np.testing.assert_array_equal(f.demand, [500.0, 510.0])
    m = metrics(f, band_min=0.0)
    ts = brentq(lambda x: abs(_second_order(np.array([x]), -10.0, -0.9, -1.1)[0][0]) - 0.2, 0.1, 30.0)
    assert m.demand_altitude == 510.0 and m.step_size == pytest.approx(10.0, abs=1e-9)
    assert ts <= m.settling_time <= ts + DT + 1e-9
    # Without the status only the published demand is known, from when it was published.
    write_flight_bag(tmp_path / "p", t, h, de, demand=[(5.0, 510.0)])
    g = Flight.from_bag(read_bag(tmp_path / "p"))
    np.testing.assert_allclose(g.demand_t, [5.0])


def _spin(tmp_path: Path, name: str, **kw: object) -> Flight:
    """Scenario 8's torque-free spin about body x at 0.8 rad/s, exact (see the test above)."""
    t = np.arange(0, 10, 0.1)
    q = np.array([axis_angle_to_quat(np.array([1.0, 0, 0]), 0.8 * x) for x in t])
    args = {"omega_B": np.tile([0.8, 0.0, 0.0], (len(t), 1)), "q": q, "throttles": np.zeros((len(t), 4)),
            "meta": {"scene": "free-spin"}, **kw}
    write_flight_bag(tmp_path / name, t, np.full(len(t), 1e6), np.zeros(len(t)), **args)
    return Flight.from_bag(read_bag(tmp_path / name))


def test_angular_momentum_drift_is_na_wherever_a_torque_acts(tmp_path: Path) -> None:
    # L_W is conserved only without external torque (eq 2): the same exact spin reports no drift
    # when the stabiliser is on, a thruster fires, the scene has a torquing model, or the scene
    # is unknown (conservation cannot be told).
    n = 100
    assert metrics(_spin(tmp_path, "free")).angular_momentum_drift < 1e-12
    assert metrics(_spin(tmp_path, "stab", stabiliser=np.ones(n, dtype=bool))).angular_momentum_drift is None
    assert metrics(_spin(tmp_path, "thrust", throttles=np.full((n, 4), 0.1))).angular_momentum_drift is None
    assert metrics(_spin(tmp_path, "mesh", meta={"scene": "tumbling-descent-mesh"})).angular_momentum_drift is None
    assert metrics(_spin(tmp_path, "unknown", meta={})).angular_momentum_drift is None


def _core_spin(dt: float, omega_B: list[float], duration: float = 10.0) -> Flight:
    """Scenario 8 flown by the core simulation (no ROS) with step ``dt`` and initial ``omega_B``."""
    import dataclasses

    scene = load_scene("free-spin")
    y = scene.initial_state.copy()
    y[S.OMEGA_B] = omega_B
    sim = Simulation(dataclasses.replace(scene, dt=dt, initial_state=y))
    rows = []
    for _ in range(int(round(duration / dt)) + 1):
        v, d = sim.state(), sim.derived()
        rows.append((v.t, v.r_W, v.v_W, v.q, d.euler, v.omega_B, d.altitude, d.climb_rate, d.mass, v.fuel))
        sim.step()
    cols = [np.array(c) for c in zip(*rows)]
    n = len(rows)
    return Flight(name=f"dt {dt}", t=cols[0], r_W=cols[1], v_W=cols[2], q=cols[3], euler=cols[4], omega_B=cols[5],
                  altitude=cols[6], climb_rate=cols[7], mass=cols[8], fuel=cols[9], throttles=np.zeros((n, 4)),
                  phase=np.zeros(n, dtype=int), gimbal_lock=np.zeros(n, dtype=bool), sequence=np.arange(1, n + 1),
                  meta={"scene": "free-spin"})


def test_drift_of_a_torque_free_flight_is_round_off_on_a_principal_axis_and_second_order_off_it() -> None:
    eps = np.finfo(float).eps
    # About a principal axis omega_dot = 0 exactly (eq 2) and the attitude turns about L itself:
    # only rounding moves L_W, a few ulps a step at most over the 100 steps.
    assert metrics(_core_spin(0.1, [0.8, 0.0, 0.0])).angular_momentum_drift <= 100 * 4 * eps
    # Off a principal axis the body nutates; Verlet is second order, so halving the step divides
    # the drift by 2^2 = 4 (the next term, O(dt^3), moves the ratio by a fraction omega dt ~ 0.09).
    d = [metrics(_core_spin(dt, [0.8, 0.3, 0.2])).angular_momentum_drift for dt in (0.1, 0.05)]
    assert 0.0 < d[1] < d[0]
    assert d[0] / d[1] == pytest.approx(4.0, rel=0.1)


def test_a_guided_descent_has_no_step_response_until_it_hovers(tmp_path: Path) -> None:
    # A de-orbit flight from 677 km demands its 500 m hover from the first state: that is the end
    # of a descent, not a step to measure (its 2 % band alone is 13.5 km).
    t = np.arange(0, 30, 0.1)
    h = 677e3 - 10.0 * t
    write_flight_bag(tmp_path / "orbit", t, h, np.full(len(t), -10.0), status_demand=np.full(len(t), 500.0),
                     status_mode=np.full(len(t), "deorbit-slew"))
    m = metrics(Flight.from_bag(read_bag(tmp_path / "orbit")))
    assert m.demand_altitude == 500.0
    assert (m.step_size, m.settling_time, m.overshoot_percent, m.steady_state_error, m.hover_error_max) == (None,) * 5
    # Once the law reports its hover, the step is measured from there: from 510 m, the closed form.
    t = np.arange(0, 40, DT)
    tau = np.clip(t - 20.0, 0.0, None)
    e, de = _second_order(tau, 10.0, -0.9, -1.1)
    h = np.where(t < 20.0, 900.0 - 19.5 * t, 500.0 + e)
    mode = np.where(t < 20.0 - 1e-9, "powered-descent", "hover")
    write_flight_bag(tmp_path / "hover", t, h, de, status_demand=np.full(len(t), 500.0), status_mode=mode)
    m = metrics(Flight.from_bag(read_bag(tmp_path / "hover")))
    ts = brentq(lambda x: _second_order(np.array([x]), 10.0, -0.9, -1.1)[0][0] - 0.5, 0.1, 30.0)
    assert m.step_size == pytest.approx(-10.0, abs=1e-9)
    assert ts <= m.settling_time <= ts + DT + 1e-9


def test_a_coast_is_not_saturation_and_a_flight_without_autopilot_has_none(tmp_path: Path) -> None:
    # The landing law asks for no thrust in its coast (clipped at zero by design); 5 s of its
    # braking at full throttle are saturation.
    t = np.arange(0, 25, 0.1)
    mode = np.where(t < 20.0 - 1e-9, "coast", "braking")
    thr = np.where((t < 20.0 - 1e-9)[:, None], 0.0, 1.0) * np.ones((1, 4))
    write_flight_bag(tmp_path / "land", t, 9000.0 - t, -np.ones(len(t)), throttles=thr, status_demand=np.zeros(len(t)),
                     status_mode=mode, status_saturated=np.ones(len(t), dtype=bool),
                     meta={"scene": "landing", "controller": "landing"})
    assert metrics(Flight.from_bag(read_bag(tmp_path / "land"))).saturation_time == pytest.approx(5.0 - 0.1, abs=1e-9)
    write_flight_bag(tmp_path / "none", t, 9000.0 - t, -np.ones(len(t)), throttles=np.zeros((len(t), 4)),
                     meta={"scene": "tumbling-descent", "controller": "none"})
    assert metrics(Flight.from_bag(read_bag(tmp_path / "none"))).saturation_time is None


def test_gimbal_lock_events_are_the_simulators_events_and_quaternion_flights_have_none(tmp_path: Path) -> None:
    # The state's flag is set wherever the derived angles are near theta = 0, twice here; only an
    # Euler-mode scene integrates the angles, and its simulator says so with GIMBAL_LOCK events.
    t = np.arange(0, 10, 0.1)
    flag = ((t > 1.0) & (t < 2.0)) | ((t > 5.0) & (t < 6.0))
    h, v = np.zeros(len(t)), np.zeros(len(t))

    def count(name: str, scene: str | None, events: list[tuple[float, int]] | None) -> int | None:
        write_flight_bag(tmp_path / name, t, h, v, gimbal_lock=flag, events=events,
                         meta={"scene": scene} if scene else None)
        return metrics(Flight.from_bag(read_bag(tmp_path / name))).gimbal_lock_events

    assert count("quaternion", "gimbal-lock-pendulum-quaternion", [(10.0, 12)]) == 0  # FLIGHT_ENDED only
    assert count("euler", "gimbal-lock-pendulum", [(1.1, GIMBAL_LOCK_KIND), (10.0, 12)]) == 1
    # A bag recorded without /lander/events: the entries into the flagged region, Euler mode only.
    assert count("euler-no-events", "gimbal-lock-pendulum", None) == 2
    assert count("quaternion-no-events", "gimbal-lock-pendulum-quaternion", None) == 0
    assert count("unknown", None, None) is None


def test_fuel_altitude_and_saturation_are_na_on_a_fixed_pivot(tmp_path: Path) -> None:
    # The seed-1 pendulum: a fixed pivot without thrusters; its tank and altitude read 0.
    t = np.arange(0, 5, 0.1)
    write_flight_bag(tmp_path / "p", t, np.zeros(len(t)), np.zeros(len(t)), throttles=np.zeros((len(t), 0)),
                     fuel=np.zeros(len(t)), meta={"scene": "gimbal-lock-pendulum", "controller": "none"})
    m = metrics(Flight.from_bag(read_bag(tmp_path / "p")))
    assert (m.fuel_used, m.final_altitude, m.saturation_time) == (None, None, None)
    # Its angles are integrated (Euler mode): the published quaternion is made from them, unit by
    # construction, so its norm measures no integrator.
    assert m.quaternion_norm_drift is None
    rows = {line.split()[0]: line.split()[-1] for line in table([m]).splitlines()[2:]}
    assert rows["fuel_used"] == "n/a" and rows["final_altitude"] == "n/a"


def test_zxz_angles_are_drawn_in_their_ranges_as_the_same_rotation() -> None:
    rng = np.random.default_rng(1)
    E = rng.uniform(-60.0, 60.0, size=(200, 3))
    C = canonical_zxz(E)
    assert np.all((C[:, 0] > -np.pi) & (C[:, 0] <= np.pi) & (C[:, 2] > -np.pi) & (C[:, 2] <= np.pi))
    assert np.all((C[:, 1] >= 0.0) & (C[:, 1] <= np.pi))
    for e, c in zip(E, C):  # eq 3: one rotation; rounding of |E| <= 60 rad is ~1e-14
        np.testing.assert_allclose(euler_to_matrix(c), euler_to_matrix(e), atol=1e-13)


def test_euler_angles_near_gimbal_lock_stay_readable_and_the_lock_is_shaded(tmp_path: Path) -> None:
    # Euler mode through the lock: phi and psi race (eq 5's 1/sin theta) to 1e11 rad.
    t = np.arange(0, 10, 0.1)
    race = np.where(t > 3.0, 1e11 * (t - 3.0), 0.0)
    E = np.column_stack([race, 0.3 * np.sin(t), -race])
    flag = (t > 3.0) & (t < 3.5)
    write_flight_bag(tmp_path / "lock", t, np.zeros(len(t)), np.zeros(len(t)), euler=E, gimbal_lock=flag,
                     meta={"scene": "gimbal-lock-pendulum"})
    fig = figures([Flight.from_bag(read_bag(tmp_path / "lock"))])["attitude"]
    ax = fig.get_axes()[0]
    ys = np.concatenate([ln.get_ydata() for ln in ax.get_lines()])
    assert np.all(np.abs(ys) <= 180.0)
    assert [p.get_gid() for p in ax.patches] == ["near gimbal lock"]
    assert "near gimbal lock" in [x.get_text() for x in ax.get_legend().get_texts()]


def test_the_z_axis_track_is_drawn_for_a_fixed_pivot_whatever_the_bags_name(tmp_path: Path) -> None:
    t = np.arange(0, 5, 0.1)
    h = np.zeros(len(t))
    write_flight_bag(tmp_path / "pendulum", t, h, h, meta={"scene": "gimbal-lock-pendulum"})
    write_flight_bag(tmp_path / "rotor-hover", t, h + 500.0, h, meta={"scene": "hover"})
    assert "ztrack" in figures([Flight.from_bag(read_bag(tmp_path / "pendulum"))])
    assert "ztrack" not in figures([Flight.from_bag(read_bag(tmp_path / "rotor-hover"))])
