"""Metrics of lander_tools.analysis against closed forms of second-order step responses
(control reference eq 19-21) and of torque-free spin, on synthetic bags; plots and comparisons."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from lander_sim.physics.rotation import axis_angle_to_quat
from lander_tools.analysis import Flight, metrics, table, to_json
from lander_tools.analysis_plots import write_plots
from lander_tools.bagio import read_bag

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
    write_flight_bag(tmp_path / "ok", t, h, np.zeros(len(t)), omega_B=w, q=q_ok, throttles=zero)
    write_flight_bag(tmp_path / "bad", t, h, np.zeros(len(t)), omega_B=w, q=q_bad, throttles=zero)
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
    ma, mb = metrics(fa), metrics(fb)
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
