"""Observability, Kalman gains and LQG (lander_autopilot/design/observability.py): rank and unobservable
directions against closed forms derived here, the double integrator's known Kalman gain, and the
separation principle."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.design import DesignError
from lander_autopilot.design.altitude import altitude_model
from lander_autopilot.design.attitude import UPRIGHT_EULER, attitude_model
from lander_autopilot.design.gains import match_poles
from lander_autopilot.design.observability import (
    discrete_kalman,
    kalman,
    lqg,
    lqg_closed_loop,
    observability,
    sensor_outputs,
)
from lander_autopilot.design.translational import FULL_STATES, full_model
from lander_sim.physics.rotation import euler_rates_matrix
from lander_sim.scenes.vehicles import lander

FUEL = 100.0


def _projector(basis: np.ndarray) -> np.ndarray:
    """Orthogonal projector onto the column space of ``basis`` (any basis, not necessarily orthonormal)."""
    if basis.shape[1] == 0:
        return np.zeros((basis.shape[0], basis.shape[0]))
    Q, _ = np.linalg.qr(basis)
    return Q @ Q.T


def _unit(names: list[str], states: tuple[str, ...] = FULL_STATES) -> np.ndarray:
    """Columns: the coordinate directions of ``names``."""
    out = np.zeros((len(states), len(names)))
    for k, n in enumerate(names):
        out[states.index(n), k] = 1.0
    return out


def _same_subspace(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(_projector(a) - _projector(b)).max())


@pytest.fixture(scope="module")
def full():
    return full_model(lander(), FUEL, 500.0)


def _full_obs(full, sensors):
    out = sensor_outputs("translational", full.states, sensors, full.B.shape[1])
    return observability(full.A, out.C)


def test_altimeter_alone_leaves_everything_but_the_vertical_channel_unobservable(full) -> None:
    # Closed form: the altimeter sees p_U; p_U'' = v_U' = 0 for every state (tilt moves the thrust
    # only horizontally to first order, and attitude and rates do not enter the vertical row), so the
    # outputs are p_U, v_U and zeros: rank 2, the other ten coordinates unobservable.
    obs = _full_obs(full, ["altimeter"])
    assert obs.rank == 2
    rest = [s for s in FULL_STATES if s not in ("p_U", "v_U")]
    assert _same_subspace(obs.unobservable, _unit(rest)) < 1e-9


def test_altimeter_and_doppler_leave_horizontal_position_and_heading_unobservable(full) -> None:
    # Closed form: velocity is measured, and v' = g C dE sees the tilt; a rotation about the local
    # vertical (body z at the upright hover) turns nothing the thrust does, so its angle and rate are
    # unseen, as is the horizontal position (no output and no state depends on it).
    obs = _full_obs(full, ["altimeter", "doppler"])
    assert obs.rank == 8
    heading = np.zeros(12)
    heading[6:9] = euler_rates_matrix(np.array(UPRIGHT_EULER)) @ np.array([0.0, 0.0, 1.0])
    expected = np.column_stack([_unit(["p_E", "p_N", "wz"]), heading])
    assert _same_subspace(obs.unobservable, expected) < 1e-9


def test_the_full_sensor_set_sees_all_but_horizontal_position(full) -> None:
    obs = _full_obs(full, ["altimeter", "doppler", "star_tracker", "gyro"])
    assert obs.rank == 10
    assert _same_subspace(obs.unobservable, _unit(["p_E", "p_N"])) < 1e-9


def test_the_accelerometer_adds_no_rank_its_output_is_the_input(full) -> None:
    # Specific force in vacuum is thrust / m, body frame: a function of the throttles alone.
    F_B = np.array([-t.direction_B * t.max_thrust for t in lander().thrusters]).T / full.mass
    out = sensor_outputs("translational", full.states, ["accelerometer"], full.B.shape[1], specific_force_D=F_B)
    assert not np.any(out.C)
    np.testing.assert_array_equal(out.D, F_B)
    assert observability(full.A, out.C).rank == 0
    with_acc = sensor_outputs("translational", full.states, ["altimeter", "accelerometer"], 4, specific_force_D=F_B)
    assert observability(full.A, with_acc.C).rank == _full_obs(full, ["altimeter"]).rank


def test_attitude_gyro_alone_cannot_find_the_attitude() -> None:
    # At rest eq 28 is E' = A12 w, w' = B u: rates integrate to angles, so the gyro sees the rates
    # and none of the angles (the constant of integration).
    att = attitude_model(lander(), FUEL)
    names = ("phi", "theta", "psi", "wx", "wy", "wz")
    gyro = observability(att.A, sensor_outputs("attitude", names, ["gyro"], 4).C)
    assert gyro.rank == 3
    assert _same_subspace(gyro.unobservable, _unit(["phi", "theta", "psi"], names)) < 1e-9
    tracker = observability(att.A, sensor_outputs("attitude", names, ["star_tracker"], 4).C)
    assert tracker.observable


def test_velocity_sees_altitude_only_through_the_gravity_gradient() -> None:
    # O = [[0, 1], [a21, 0]] with a21 = 2GM/z^3: rank 2 with the gradient, its smallest singular
    # value a21; rank 1 under eq 16's constant gravity.
    names = ("z", "z_dot")
    C = sensor_outputs("altitude", names, ["doppler"], 1).C
    flat = observability(altitude_model(lander(), FUEL, 500.0).A, C)
    assert flat.rank == 1
    assert _same_subspace(flat.unobservable, _unit(["z"], names)) < 1e-12
    m = altitude_model(lander(), FUEL, 500.0, gravity_gradient=True)
    grad = observability(m.A, C, rtol=1e-12)
    assert grad.rank == 2
    assert grad.singular_values[-1] == pytest.approx(m.A[1, 0], rel=1e-12)


def test_kalman_gain_of_the_double_integrator_is_the_butterworth_filter() -> None:
    # x'' = w (density q), y = x + v (density r): the Riccati equation solves in closed form to
    # L = [sqrt(2) (q/r)^(1/4), (q/r)^(1/2)], estimator poles wn (-1 +- j)/sqrt(2), wn = (q/r)^(1/4).
    q, r = 0.04, 2.5
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    d = kalman(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), [[q]], [[r]])
    wn = (q / r) ** 0.25
    np.testing.assert_allclose(d.L.ravel(), [math.sqrt(2.0) * wn, wn * wn], rtol=1e-10)
    np.testing.assert_allclose(d.P, r * np.array([[math.sqrt(2.0) * wn, wn * wn], [wn * wn, math.sqrt(2.0) * wn**3]]),
                               rtol=1e-10)
    assert match_poles(d.poles, wn * np.array([-1 + 1j, -1 - 1j]) / math.sqrt(2.0)) < 1e-10


def test_the_discrete_gain_tends_to_the_continuous_one_as_the_sample_shrinks() -> None:
    # With R_N = sigma^2 dt, the sampled filter's gain per unit time L_d / dt tends to the
    # continuous gain as dt -> 0; the gap is first order in dt.
    q, sigma2 = 0.04, 0.25
    A, G, C = np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    errs = []
    for dt in (0.01, 0.001):
        Lc = kalman(A, G, C, [[q]], [[sigma2 * dt]]).L.ravel()
        Ld = discrete_kalman(A, G, C, [[q]], [[sigma2]], dt).L.ravel()
        errs.append(float(np.abs(Ld / dt - Lc).max() / np.abs(Lc).max()))
    assert errs[1] < errs[0] / 5.0  # first order: a tenth of dt gives about a tenth of the gap
    assert errs[1] < 0.05


def test_horizontal_position_is_not_detectable_so_no_kalman_gain(full) -> None:
    out = sensor_outputs("translational", full.states, ["altimeter", "doppler", "star_tracker", "gyro"], 4)
    with pytest.raises(DesignError, match="detectable"):
        kalman(full.A, np.eye(12), out.C, np.eye(12) * 1e-4, np.eye(out.C.shape[0]) * 1e-2)


@pytest.mark.parametrize("model", ["altitude", "attitude"])
def test_lqg_closed_loop_poles_are_the_regulator_and_estimator_poles(model: str) -> None:
    v = lander()
    if model == "altitude":
        m = altitude_model(v, FUEL, 500.0)
        A, B = m.A, m.B
        C = sensor_outputs("altitude", ("z", "z_dot"), ["altimeter", "doppler"], 1).C
        Q, R = np.diag([1.0, 1.0]), np.eye(1) * 10.0
        G, QN, RN = np.array([[0.0], [1.0]]), np.eye(1) * 0.01, np.diag([4.0, 0.01])
    else:
        m = attitude_model(lander("canted"), FUEL)  # canted: all three axes controllable
        A, B = m.A, m.B
        C = sensor_outputs("attitude", ("phi", "theta", "psi", "wx", "wy", "wz"), ["star_tracker", "gyro"], 4).C
        Q, R = np.eye(6), np.eye(4)
        G, QN, RN = np.vstack([np.zeros((3, 3)), np.eye(3)]), np.eye(3) * 1e-4, np.diag([1e-8] * 3 + [1e-6] * 3)
    d = lqg(A, B, C, Q, R, G, QN, RN)
    union = np.concatenate([d.regulator_poles, d.estimator_poles])
    assert match_poles(union, d.poles) < 1e-8 * max(1.0, float(np.abs(union).max()))
    assert np.all(d.poles.real < 0.0)
    # the same closed loop through python-control's own interconnection of plant and compensator
    import control

    plant = control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1])))
    comp = control.ss(A - B @ d.K - d.L @ C, d.L, -d.K, np.zeros((B.shape[1], C.shape[0])))
    loop = control.feedback(plant, comp, sign=1)
    assert match_poles(union, np.linalg.eigvals(loop.A)) < 1e-8 * max(1.0, float(np.abs(union).max()))


def test_separation_holds_for_any_gains_not_only_optimal_ones() -> None:
    # Block-triangular in (x, e): true for arbitrary K and L, stable or not.
    rng = np.random.default_rng(3)
    A, B, C = rng.normal(size=(4, 4)), rng.normal(size=(4, 2)), rng.normal(size=(2, 4))
    K, L = rng.normal(size=(2, 4)), rng.normal(size=(4, 2))
    poles = np.linalg.eigvals(lqg_closed_loop(A, B, C, K, L))
    union = np.concatenate([np.linalg.eigvals(A - B @ K), np.linalg.eigvals(A - L @ C)])
    assert match_poles(union, poles) < 1e-8 * max(1.0, float(np.abs(union).max()))


def test_bad_input_names_what_was_wrong() -> None:
    with pytest.raises(DesignError, match="unknown sensor 'sonar'"):
        sensor_outputs("altitude", ("z", "z_dot"), ["sonar"], 1)
    with pytest.raises(DesignError, match="C must have 2 columns"):
        observability(np.eye(2), np.eye(3))
    with pytest.raises(DesignError, match="positive definite"):
        kalman(np.eye(2), np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2)))


def test_the_design_reports_sensor_section_shows_the_ranks_and_the_separation() -> None:
    from lander_autopilot.design.report import format_sensors_report, sensors_report

    rep = sensors_report(lander("canted"), FUEL, ("altimeter", "doppler", "star_tracker", "gyro", "accelerometer"))
    assert [rep[k]["observability_rank"] for k in ("altitude", "attitude", "translational")] == [2, 6, 10]
    assert rep["altitude"]["lqg"]["separation_error"] < 1e-8
    only = sensors_report(lander("canted"), FUEL, ("doppler",))
    assert only["altitude"]["observability_rank"] == 1 and "kalman" not in only["altitude"]
    assert "not observable with these sensors" in format_sensors_report(only)


def test_lander_design_sensors_prints_the_section_and_refuses_an_unknown_sensor(capsys) -> None:
    import argparse

    from lander_tools.commands import design

    parser = argparse.ArgumentParser()
    design.add_arguments(parser)
    assert design.run(parser.parse_args(["hover-canted", "--sensors", "altimeter", "doppler"])) == 0
    out = capsys.readouterr().out
    assert "== Sensors: altimeter doppler" in out and "separation: closed-loop poles" in out
    assert design.run(parser.parse_args(["hover-canted", "--sensors", "sonar"])) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown sensor 'sonar'" in err[0]
