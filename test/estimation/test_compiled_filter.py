"""The compiled navigation filter against the Python one: the same state to rounding on random inputs.

Tolerance: the kernels sum the 15-term products in another order than numpy's BLAS, and the scalar
Joseph update is expanded (the same matrix in exact arithmetic). Each product's rounding differs by
at most about ``15 eps |P|`` (eps = 2.2e-16); a well-conditioned filter does not amplify such errors
(the Joseph form is stable to first order: Bucy and Joseph 1968), so after ``K`` steps the
difference grows at most like ``K * 15 eps`` ~ 1e-12 relative for the 300 steps flown here. The test
allows 1e-9 relative: a thousand times that bound, and still a million times below any
difference that would matter (the smallest standard deviation, the gyro bias's ~1e-6 rad/s
against a state of O(1)).
"""
from __future__ import annotations

import numpy as np
import pytest

from lander_autopilot.estimation.compiled import CompiledNavFilter, compiled_copy
from lander_autopilot.estimation.ekf import N_ERR, NavFilter, NavState, NoiseModel, small_rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.rotation import quat_mult, quat_normalise

RTOL = 1e-9


def random_filter(rng: np.random.Generator) -> NavFilter:
    """A filter at a random state 100 m - 5 km above Mars with a random positive-definite P."""
    rhat = rng.standard_normal(3)
    rhat /= np.linalg.norm(rhat)
    A = rng.standard_normal((N_ERR, N_ERR))
    scale = np.repeat([10.0, 0.5, 0.02, 1e-5, 3e-3], 3)
    P = (A @ A.T / N_ERR + np.eye(N_ERR)) * np.outer(scale, scale)
    state = NavState(r_W=(MARS_RADIUS + rng.uniform(100.0, 5000.0)) * rhat, v_W=rng.normal(0.0, 20.0, 3),
                     q=quat_normalise(rng.standard_normal(4)), b_g=rng.normal(0.0, 1e-5, 3),
                     b_a=rng.normal(0.0, 3e-3, 3), P=P, t=0.0)
    noise = NoiseModel(2.0e-5, 4.9e-4, 8.1e-9, 4.9e-6)
    return NavFilter(state, noise, planet_radius=MARS_RADIUS)


def drive(filt: NavFilter, rng: np.random.Generator, steps: int) -> list[float]:
    """Propagate on random IMU samples and apply every kind of update with random measurements;
    the NIS of each update."""
    nis = []
    for k in range(steps):
        filt.propagate(rng.normal(0.0, 0.05, 3), rng.normal(0.0, 4.0, 3), float(rng.uniform(0.005, 0.1)))
        which = k % 4
        s = filt.state
        if which == 0:
            q_m = quat_normalise(quat_mult(s.q, small_rotation(rng.normal(0.0, 1e-3, 3))))
            u = filt.update_star_tracker(q_m, np.full(3, 1.5e-4))
        elif which == 1:
            u = filt.update_altimeter(float(np.linalg.norm(s.r_W) - MARS_RADIUS + rng.normal(0.0, 5.0)), 2.0,
                                      np.array([0.0, 0.0, -1.0]))
        elif which == 2:
            u = filt.update_doppler(rng.normal(0.0, 20.0, 3), np.full(3, 0.2))
        else:
            u = filt.update_ground_fix(np.concatenate((s.r_W + rng.normal(0.0, 50.0, 3), s.v_W + rng.normal(0.0, 1.0, 3))),
                                       np.concatenate((np.full(3, 100.0), np.full(3, 1.0))))
        if u is not None:
            nis.append(u.nis)
    return nis


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(np.max(np.abs(b)), 1e-300))


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_filter_keeps_the_python_filters_state_to_rounding(seed):
    py = random_filter(np.random.default_rng(seed))
    cf = compiled_copy(py)
    assert isinstance(cf, CompiledNavFilter)
    nis_py = drive(py, np.random.default_rng(1000 + seed), 300)
    nis_c = drive(cf, np.random.default_rng(1000 + seed), 300)
    a, b = cf.state, py.state
    for name in ("r_W", "v_W", "q", "b_g", "b_a"):
        assert rel(getattr(a, name), getattr(b, name)) <= RTOL, name
    # P per block, each against its own size (the blocks span 12 orders of magnitude)
    for i in range(5):
        for j in range(5):
            blk = (slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3))
            ref = np.sqrt(np.outer(np.diag(b.P)[3 * i:3 * i + 3], np.diag(b.P)[3 * j:3 * j + 3]))
            assert np.max(np.abs(a.P[blk] - b.P[blk]) / ref) <= RTOL, (i, j)
    assert np.allclose(nis_c, nis_py, rtol=RTOL, atol=0.0)
    assert a.t == b.t
    assert np.array_equal(a.P, a.P.T)  # symmetrised as the Python filter's


def test_the_compiled_filter_refuses_bad_input_as_the_python_one():
    cf = compiled_copy(random_filter(np.random.default_rng(7)))
    before = cf.state.P.copy()
    with pytest.raises(ValueError, match="imu: dt must be a finite number > 0 s"):
        cf.propagate(np.zeros(3), np.zeros(3), 0.0)
    with pytest.raises(ValueError, match="doppler: expected 3 finite numbers"):
        cf.update_doppler(np.array([0.0, np.nan, 0.0]), np.ones(3))
    assert cf.rejected == {"imu": 1, "doppler": 1}
    assert np.array_equal(cf.state.P, before)
