"""Seed 1 (dynamics), lander tasks 1-2 as scripted flights: scenario 8's free spin and the
single-thruster spin-up, flown by the real sim node, recorded, and checked from the bag."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lander_sim.physics import rotation
from lander_sim.scenes import load_scene
from lander_tools.analysis import Flight, angular_momentum_W, metrics

from .flightcheck import check_bag, fly_shipped


def test_scenario8_spins_at_a_constant_rate_anticlockwise(tmp_path: Path) -> None:
    result, bag_path = fly_shipped("seed1-scenario8-spin", tmp_path, storage="sqlite3")
    assert result.outcome == "time-limit" and result.sim_time == pytest.approx(30.0, abs=1e-9)
    f = Flight.from_bag(check_bag(bag_path, result))
    assert f.t[-1] == pytest.approx(30.0, abs=1e-9)
    # omega along a principal axis: omega x I omega = 0 (eq 2), so omega_dot is exactly zero and
    # every integrator keeps omega = (0.8, 0, 0) to the last bit.
    np.testing.assert_array_equal(f.omega_B, np.tile([0.8, 0.0, 0.0], (len(f.t), 1)))
    # The attitude turns about body x at +0.8 rad/s (anticlockwise about the spin axis):
    # q(t) = q0 x q_x(0.8 t). Verlet's attitude update is second order: with 0.8 rad/s and the
    # scene's dt = 0.1 s the local error is <= (omega dt)^3 / 6 = 8.5e-5 rad a step, at most
    # 300 steps * 8.5e-5 = 0.026 rad after 30 s.
    q0 = f.q[0]
    for t, q in zip(f.t, f.q):
        exact = rotation.quat_mult(q0, rotation.axis_angle_to_quat(np.array([1.0, 0, 0]), 0.8 * t))
        angle = 2 * np.arccos(min(1.0, abs(float(np.dot(exact, q)))))
        assert angle <= 0.026 + 1e-12, f"t = {t}: attitude off by {angle} rad"
    m = metrics(f)
    assert m.fuel_used == 0.0 and m.final_spin_rate == pytest.approx(0.8, abs=0)


def test_single_thruster_spin_up_obeys_the_angular_impulse_theorem(tmp_path: Path) -> None:
    result, bag_path = fly_shipped("seed1-scenario8-spin-up", tmp_path)
    f = Flight.from_bag(check_bag(bag_path, result))
    vehicle = load_scene("free-spin").vehicle
    th = vehicle.thrusters[1]
    # Throttle 0.2 answered to the state at t = 2.0 s and zeroed at t = 7.0 s (lockstep): 5 s of
    # thrust burning 0.2 * 0.5 kg/s. Exact up to float rounding of the step count.
    assert metrics(f).fuel_used == pytest.approx(0.2 * th.fuel_rate * 5.0, abs=1e-9)
    i0, i1 = np.searchsorted(f.t, [2.0 - 1e-9, 7.0 - 1e-9])
    L = angular_momentum_W(f)
    # Torque of the thruster in the body frame, tau_B = p x (-d t T) (seed 1 task 2); then
    # dL_W/dt = R(q)^T tau_B, integrated over the burn by the trapezoid rule on the 10 Hz states.
    tau_B = np.cross(th.position_B, -th.direction_B * 0.2 * th.max_thrust)
    torque_W = np.array([rotation.quat_to_matrix(q).T @ tau_B for q in f.q[i0 : i1 + 1]])
    impulse = np.trapezoid(torque_W, f.t[i0 : i1 + 1], axis=0)
    dL = L[i1] - L[i0]
    # Trapezoid error ~ h^2 omega^2 / 12 of the impulse (h = 0.1 s, omega <= 3.3 rad/s): 0.9 %;
    # the integrator's own O(dt^2) error is of the same size. 3 % holds both with margin.
    assert np.linalg.norm(dL - impulse) <= 0.03 * np.linalg.norm(impulse)
    # The lander spins away from the thrust: the spin rate grows from 0.8 rad/s.
    assert np.linalg.norm(f.omega_B[i1]) > 2.0
    # Before and after the burn the flight is torque-free: L_W keeps its value. Verlet's O(dt^2)
    # error with omega dt <= 0.33 is bounded by (omega dt)^2 / 12 = 0.9 % per unit of |L|.
    for a, b in ((0, i0), (i1 + 1, len(f.t) - 1)):
        assert np.linalg.norm(L[b] - L[a]) <= 0.01 * np.linalg.norm(L[a])
