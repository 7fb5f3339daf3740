"""In-flight calibration of the de-orbit laws' models (lander_autopilot/controllers/calibration.py):
the thrust measured in the de-orbit burn and the drag scale and wind fitted under the chute, on
synthetic data (exact) and in a dispersed core-only flight (against the case's true dispersions)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.controllers.calibration import ChuteDragFit, ThrustCalibration


def test_thrust_calibration_is_the_ratio_of_measured_to_modelled_thrust_acceleration():
    cal = ThrustCalibration()
    assert cal.scale == 1.0  # nothing measured yet: the model as it is
    g = np.array([0.0, 0.0, -3.0])
    rng = np.random.default_rng(1)
    for _ in range(50):
        thrust, mass = rng.uniform(3000.0, 4000.0), rng.uniform(150.0, 200.0)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        cal.add(g + 0.97 * thrust / mass * axis, g, thrust, mass)  # 3 % less than modelled
    assert cal.scale == pytest.approx(0.97, rel=1e-12)
    wild = ThrustCalibration()
    wild.add(np.array([0.0, 0.0, 20.0]), np.zeros(3), 1000.0, 100.0)  # twice the model: a fault
    assert wild.scale == 1.0 + ThrustCalibration.LIMIT


def _coast(scale: float, wind_W: np.ndarray, n: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A fall under a canopy from 180 m/s at 40 degrees to 40 m/s vertical: velocities [m/s], K [1/m]
    and the drag ``-s K |v - w| (v - w)`` [m/s^2] (world frame, z up)."""
    tau = np.linspace(0.0, 1.0, n)
    speed = 40.0 + 140.0 * np.exp(-5.0 * tau)
    angle = math.radians(40.0) * np.exp(-6.0 * tau)
    V = np.stack([speed * np.sin(angle), 0.3 * speed * np.sin(angle), -speed * np.cos(angle)], axis=1)
    K = 0.002 * np.exp(tau)  # [1/m]: the air thickens as the lander falls
    va = V - wind_W
    A = -(scale * K * np.linalg.norm(va, axis=1))[:, None] * va
    return V, K, A


def test_chute_drag_fit_recovers_the_density_scale_and_the_wind_exactly_from_noise_free_drag():
    truth_s, truth_w = 0.87, np.array([-2.4, 2.9, -1.1])
    fit = ChuteDragFit()
    for v, k, a in zip(*_coast(truth_s, truth_w)):
        fit.add(v, a, k)
    got = fit.solve(1.0, np.zeros(3))  # from the model's scale and still air
    assert got is not None and got.samples == 400
    # Gauss-Newton on a zero-residual problem converges quadratically: to round-off
    assert got.scale == pytest.approx(truth_s, rel=1e-9)
    np.testing.assert_allclose(got.wind_W, truth_w, atol=1e-7)
    assert got.rms < 1e-9


def test_chute_drag_fit_separates_the_vertical_wind_from_the_scale_that_a_terminal_fall_cannot():
    # At one speed a scale and a vertical wind are the same drag; over the slowing fall they are not.
    # With noise (0.05 m/s^2 per sample per axis, the level of a 0.1 s difference of velocities in a
    # gust) the fit's error is that noise's over ~400 samples: well under the 1 m/s it finds.
    truth_s, truth_w = 1.1, np.array([0.5, -1.0, 1.5])
    V, K, A = _coast(truth_s, truth_w)
    A = A + np.random.default_rng(7).normal(scale=0.05, size=A.shape)
    fit = ChuteDragFit()
    for v, k, a in zip(V, K, A):
        fit.add(v, a, k)
    got = fit.solve(1.0, np.zeros(3))
    assert got is not None
    assert abs(got.scale / truth_s - 1.0) < 0.01
    assert abs(got.wind_W[2] - truth_w[2]) < 0.2
    assert got.rms == pytest.approx(0.05, rel=0.1)  # the residual is the noise put in
    few = ChuteDragFit()
    for v, k, a in list(zip(V, K, A))[:7]:
        few.add(v, a, k)
    assert few.solve(1.0, np.zeros(3)) is None  # too few periods to fit four unknowns
    terminal = ChuteDragFit()  # the coast's last third, 41-45 m/s: scale and wind not separable
    for v, k, a in list(zip(V, K, A))[-130:]:
        terminal.add(v, a, k)
    assert terminal.solve(1.0, np.zeros(3)) is None


def test_a_dispersed_flight_measures_its_thrust_in_the_burn_and_fits_its_air_under_the_chute():
    """A named regression from 200 km, thin air in a downdraft (thrust -0.55 %, dry mass +1.1 %,
    density -12.9 %, 1.13 m/s of downdraft at the site), flown core-only to its powered descent:
    the law's estimates against the flight's truth."""
    from deorbit_regressions import THIN_AIR_DOWNDRAFT, flown

    from lander_autopilot.controllers.deorbit import Phase

    case = THIN_AIR_DOWNDRAFT.flight_case()
    wind_W = np.asarray(case.wind_mean_W)
    assert case.density_error < -0.1  # the regression this is: thin air ...
    for state, ctrl, _sim in flown(THIN_AIR_DOWNDRAFT, 0):  # noqa: B007 - state, ctrl: read after the loop
        if ctrl.phase is Phase.POWERED:
            break
    else:
        raise AssertionError("no powered descent")
    mass = ctrl.vehicle.mass(state.fuel)  # the model's mass at the handover
    true_thrust = (1.0 + float(np.mean(case.thrust_error))) * mass / (mass + ctrl.vehicle.dry_mass * case.mass_error)
    # measured at the burn's mass, not the handover's (the dry mass error's share grows as fuel
    # burns: ~2e-4 here); the thrusters' cant (<= 0.5 deg: 4e-5) and the attitude law's differential
    # on thrusters rated up to 6 % apart (~1 % of the collective: <= 6e-4) are in it too
    assert ctrl.thrust_calibration.scale == pytest.approx(true_thrust, abs=1e-3)
    fit = ctrl.air
    assert fit is not None and fit.samples > 500
    up = state.r_W / np.linalg.norm(state.r_W)
    assert float(wind_W @ up) < -1.0  # ... and a downdraft over 1 m/s
    # measured over modelled drag per modelled mass: the density's error and the mass's together
    true_air = (1.0 + case.density_error) * mass / (mass + ctrl.vehicle.dry_mass * case.mass_error)
    # the drag scale learnt at the canopy's terminal speed alone is 6 % off here (0.818 against
    # 0.866); the fit is within 1 % (the gusts, 0.70 m/s, are its noise), and finds the downdraft
    # the scale had folded in
    assert abs(ctrl.descent.drag_scale / true_air - 1.0) > 0.05
    assert fit.scale == pytest.approx(true_air, rel=0.01)
    assert float(fit.wind_W @ up) == pytest.approx(float(np.asarray(case.wind_mean_W) @ up), abs=0.2)
