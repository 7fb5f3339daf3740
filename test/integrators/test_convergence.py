"""Observed order of convergence of each fixed-step method against closed-form solutions."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.integrators import make
from lander_sim.integrators.reference import kepler_state, quat_distance, symmetric_top
from lander_sim.physics import rotation

from .problems import KeplerTop, state

# A symmetric top (A = B = 2, C = 4 kg m^2, spin 2 rad/s) whose centre of mass flies an e = 0.3
# Kepler orbit (GM = 1, a = 1): smooth, with closed forms for position, attitude and body rate,
# so translation and rotation are checked together. T = 2 s is a third of an orbit.
GM, A_AXIS, ECC = 1.0, 1.0, 0.3
A, C = 2.0, 4.0
Q0 = rotation.axis_angle_to_quat(np.array([1.0, 0.5, 0.2]), 0.7)
W0 = np.array([0.5, -0.3, 2.0])
T = 2.0


def _errors(name: str, dt: float, attitude: str = "quaternion") -> np.ndarray:
    """(position error, attitude error, body-rate error) at T for integrator ``name`` and step ``dt``."""
    dyn = KeplerTop((A, A, C), gm=GM, attitude=attitude)
    r0, v0 = kepler_state(0.0, GM, A_AXIS, ECC)
    att0 = Q0 if attitude == "quaternion" else rotation.quat_to_euler(Q0)
    y = state(r0, v0, att0, W0)
    integ = make(name)
    n = round(T / dt)
    for i in range(n):
        integ.step(dyn, i * dt, y, dt)
    r, _ = kepler_state(T, GM, A_AXIS, ECC)
    q, w = symmetric_top(T, A, C, Q0, W0)
    q_num = y[6:10] if attitude == "quaternion" else rotation.euler_to_quat(y[6:9])
    return np.array([np.linalg.norm(y[0:3] - r), quat_distance(q_num, q), np.linalg.norm(y[10:13] - w)])


def _slopes(name: str, dts: list[float], attitude: str = "quaternion") -> np.ndarray:
    errs = np.array([_errors(name, dt, attitude) for dt in dts])
    logdt = np.log(dts)
    return np.array([np.polyfit(logdt, np.log(errs[:, k]), 1)[0] for k in range(3)])


# Step ranges: errors stay between ~1e-2 and ~1e-11, far above round-off (1e-16 per step times
# at most 1e3 steps), and the largest step is small enough (omega dt <= 0.1) to be asymptotic.
# Tolerance +-0.25 on the fitted slope: over a factor 8 in dt the next error term changes the
# slope by O(dt) relative terms, measured here at < 0.07; a method of the wrong order misses
# by >= 1.
CASES = [
    ("symplectic-euler", 1, [0.02, 0.01, 0.005, 0.0025]),
    ("verlet", 2, [0.04, 0.02, 0.01, 0.005]),
    ("geometric", 2, [0.04, 0.02, 0.01, 0.005]),
    ("rk4", 4, [0.04, 0.02, 0.01, 0.005]),
]


@pytest.mark.parametrize(("name", "order", "dts"), CASES, ids=[c[0] for c in CASES])
def test_observed_order_matches_theory_for_translation_and_rotation(name: str, order: int, dts: list[float]) -> None:
    slopes = _slopes(name, dts)
    assert make(name).order == order
    assert np.all(np.abs(slopes - order) < 0.25), f"{name}: slopes (position, attitude, rate) = {slopes}"


@pytest.mark.parametrize(("name", "order"), [("verlet", 2), ("rk4", 4), ("symplectic-euler", 1)])
def test_euler_angle_route_converges_at_the_same_order(name: str, order: int) -> None:
    # theta stays near 1.3 rad here (far from gimbal lock), so eq 5-7 are smooth and the
    # Euler-angle route must show the method's order too; same tolerance reasoning as above.
    dts = [0.02, 0.01, 0.005, 0.0025] if order == 1 else [0.04, 0.02, 0.01, 0.005]
    slopes = _slopes(name, dts, attitude="euler")
    assert np.all(np.abs(slopes - order) < 0.25), f"{name} (euler): slopes = {slopes}"


def test_verlet_without_renormalisation_is_still_second_order_in_rotation_but_lets_norm_drift() -> None:
    # Verlet's attitude update q + q'(omega_half) dt lacks the -|w|^2 dt^2 q / 8 term of eq 15,
    # which only changes |q|: renormalising removes it. Without, |q| grows by O(dt^2) per step,
    # i.e. |q| - 1 = O(dt) after a fixed time: halving dt must halve the drift (slope 1 +- 0.25).
    drifts = []
    for dt in (0.02, 0.01, 0.005):
        dyn = KeplerTop((A, A, C), gm=GM)
        y = state(*kepler_state(0.0, GM, A_AXIS, ECC), Q0, W0)
        integ = make("verlet", renormalise=False)
        for i in range(round(T / dt)):
            integ.step(dyn, i * dt, y, dt)
        drifts.append(abs(math.sqrt(float(y[6:10] @ y[6:10])) - 1.0))
    slope = np.polyfit(np.log([0.02, 0.01, 0.005]), np.log(drifts), 1)[0]
    assert abs(slope - 1.0) < 0.25, f"|q| drift slope {slope}, drifts {drifts}"
