"""The adaptive Dormand-Prince method: tolerance met against the analytic Kepler flow."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.integrators import IntegratorError, make

from lander_sim.integrators.reference import kepler_propagate, kepler_state
from .problems import KeplerTop, state

GM, A_AXIS, ECC = 1.0, 1.0, 0.3
PERIOD = 2.0 * math.pi  # sqrt(a^3 / GM) * 2 pi


def _one_orbit(tol: float, n_outputs: int = 50):
    """One orbit with output every PERIOD/n_outputs; returns (integrator, final y, worst local ratio)."""
    worst = [0.0]

    def observer(t: float, y0: np.ndarray, y1: np.ndarray, h: float) -> None:
        # True local error of this internal step: the analytic two-body flow from y0 over h.
        r, v = kepler_propagate(y0[0:3], y0[3:6], GM, h)
        scale = tol + tol * np.maximum(np.abs(y0[0:6]), np.abs(y1[0:6]))
        worst[0] = max(worst[0], float(np.max(np.abs(np.concatenate((y1[0:3] - r, y1[3:6] - v))) / scale)))

    dyn = KeplerTop((1.0, 1.0, 1.0), gm=GM)
    y = state(*kepler_state(0.0, GM, A_AXIS, ECC), [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    integ = make("adaptive", rtol=tol, atol=tol, observer=observer)
    dt = PERIOD / n_outputs
    for i in range(n_outputs):
        integ.step(dyn, i * dt, y, dt)
    return integ, y, worst[0]


@pytest.mark.parametrize("tol", [1e-6, 1e-8, 1e-10])
def test_every_step_meets_the_requested_tolerance_on_a_kepler_orbit(tol: float) -> None:
    # rtol/atol bound the local error of each step (as in scipy's solve_ivp). The estimate is
    # that of the embedded 4th-order solution while the 5th-order one is propagated, so the
    # true local error - measured against the exact two-body flow from each step's start - must
    # be within tolerance in every component: ratio <= 1, no slack added.
    integ, y, worst = _one_orbit(tol)
    assert worst <= 1.0
    assert integ.accepted > 0 and integ.max_error <= 1.0
    # Global error after one orbit, reported in docs/integrators.md: local errors accumulate
    # over ~50-150 steps and are amplified by the orbit's shear, so the global error is
    # 10-150 x tol; a broken controller would be off by orders of magnitude more.
    r_exact, _ = kepler_state(PERIOD, GM, A_AXIS, ECC)
    assert np.linalg.norm(y[0:3] - r_exact) / A_AXIS < 300.0 * tol


def test_output_instants_are_hit_exactly_and_the_step_size_survives_between_calls() -> None:
    # Many output instants (1000 per orbit) must not force tiny internal steps: with the natural
    # step kept across calls, the count of internal steps stays close to the number of calls
    # (one per call at most, plus rejections), not a multiple of it.
    integ, y, _ = _one_orbit(1e-8, n_outputs=1000)
    assert integ.accepted <= 1000 + 5
    integ2, y2, _ = _one_orbit(1e-8, n_outputs=10)
    # Sparse outputs: a handful of outputs, still ~70 accepted steps chosen by the error alone.
    assert 30 < integ2.accepted < 200


@pytest.mark.parametrize(("key", "value"), [("rtol", 0.0), ("atol", -1.0), ("rtol", float("nan"))])
def test_bad_tolerances_are_rejected_naming_the_option(key: str, value: float) -> None:
    with pytest.raises(IntegratorError, match=repr(key)):
        make("adaptive", **{key: value})
