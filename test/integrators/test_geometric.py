"""The geometric (DLM splitting + exponential map) integrator: invariants by construction."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.integrators import IntegratorError, make
from lander_sim.integrators.free_rotor import free_rotor_run, free_rotor_step
from lander_sim.physics import rotation

from .problems import KeplerTop, state

# Asymmetric top spinning almost about its intermediate axis (B): the Dzhanibekov flip, the
# hardest torque-free case (a homoclinic orbit; the spin axis turns over every few seconds).
INERTIA = np.array([1.0, 2.0, 3.0])
OMEGA0 = np.array([0.01, 2.0, 0.01])


def _energy(L: np.ndarray) -> float:
    return 0.5 * float(np.sum(L * L / INERTIA))


def test_principal_axis_substeps_are_the_exponential_map() -> None:
    # With L along one principal axis only that axis' flow moves, so one DLM step must equal
    # rotation.quat_exp_step with omega = L_i / I_i about that axis, to round-off (1e-15).
    q0 = rotation.axis_angle_to_quat(np.array([0.3, -1.0, 0.5]), 1.1)
    for axis in range(3):
        L = np.zeros(3)
        L[axis] = 1.7
        out = free_rotor_step(*q0, *L, *INERTIA, 0.3)
        expected = rotation.quat_exp_step(q0, L / INERTIA, 0.3)
        assert np.allclose(out[:4], expected, rtol=0.0, atol=1e-15)
        assert np.allclose(out[4:], L, rtol=0.0, atol=1e-15)


def test_splitting_energy_error_is_bounded_and_not_growing_over_1e5_steps() -> None:
    # Symplectic and time-reversible: backward error analysis gives a modified energy conserved
    # to O(exp(-c/dt)), so the true energy error is O(dt^2) and oscillates with no trend.
    # Compare the largest error in the first and the last tenth of 1e5 steps (dt = 0.01 s,
    # ~30 flips): a linear drift would make the last tenth >= 10x the first; we allow 1.5x for
    # the different phases of the oscillation sampled in each window. Also |E error| must be
    # of the O(dt^2) size: below (|w| dt)^2 = 4e-4 relative.
    q = np.array([1.0, 0.0, 0.0, 0.0])
    L = INERTIA * OMEGA0
    e0 = _energy(L)
    n_chunks, per_chunk, dt = 100, 1000, 0.01
    err = np.empty(n_chunks)
    for k in range(n_chunks):
        worst = 0.0
        for _ in range(per_chunk // 10):
            free_rotor_run(q, L, INERTIA, dt, 10)
            worst = max(worst, abs(_energy(L) / e0 - 1.0))
        err[k] = worst
    first, last = err[:10].max(), err[-10:].max()
    assert last <= 1.5 * first, f"energy error grows: first tenth {first:.3e}, last tenth {last:.3e}"
    assert err.max() < (2.0 * 0.01) ** 2
    # Each substep is an exact rotation of L_B: |L_B| is conserved to round-off.
    assert abs(np.linalg.norm(L) / np.linalg.norm(INERTIA * OMEGA0) - 1.0) < 1e-12


def test_exponential_map_keeps_unit_quaternion_without_renormalising_over_1e6_steps() -> None:
    # Each substep multiplies q by (cos, sin e_i), an exactly unit quaternion up to rounding, so
    # |q| - 1 performs a random walk of ~1e-16 per substep: ~sqrt(5e6) * 1e-16 ~ 2e-13 after
    # 1e6 steps, inside the 1e-12 asked of it. (Verlet without renormalisation drifts
    # at O(dt^2) per step instead; see test_convergence.)
    q = rotation.axis_angle_to_quat(np.array([0.2, 1.0, -0.4]), 0.9)
    L = INERTIA * np.array([3.0, -5.0, 40.0])  # fast spin, 40 rad/s, as after a burn-out
    worst = 0.0
    for _ in range(100):
        free_rotor_run(q, L, INERTIA, 0.001, 10_000)
        worst = max(worst, abs(math.sqrt(float(q @ q)) - 1.0))
    assert worst < 1e-12


def test_world_angular_momentum_is_conserved_by_the_full_step() -> None:
    # L_W = R(q)^T I omega is fixed for a free body; each DLM substep conserves it exactly,
    # so after 2000 steps of the general Geometric.step it may move by round-off only
    # (2000 steps x 5 substeps x 1e-16 relative -> 1e-12 bound).
    dyn = KeplerTop(tuple(INERTIA), translation=False)
    y = state(np.zeros(3), np.zeros(3), rotation.axis_angle_to_quat(np.array([1.0, 1.0, 0.0]), 0.4), OMEGA0)
    L0_W = rotation.body_to_world(y[6:10], INERTIA * y[10:13])
    integ = make("geometric")
    for i in range(2000):
        integ.step(dyn, i * 0.01, y, 0.01)
    L_W = rotation.body_to_world(y[6:10], INERTIA * y[10:13])
    assert np.linalg.norm(L_W - L0_W) / np.linalg.norm(L0_W) < 1e-12


def test_geometric_rejects_euler_angle_scenes_naming_the_alternatives() -> None:
    dyn = KeplerTop(tuple(INERTIA), translation=False, attitude="euler")
    y = state(np.zeros(3), np.zeros(3), np.array([0.1, 1.0, 0.2]), OMEGA0)
    with pytest.raises(IntegratorError, match="needs attitude 'quaternion'.*verlet"):
        make("geometric").step(dyn, 0.0, y, 0.01)
