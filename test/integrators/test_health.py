"""The numerical-health report: invariant drift of a run and the adaptive counters."""
from __future__ import annotations

import numpy as np

from lander_sim.integrators import make
from lander_sim.integrators.health import HealthMonitor, angular_momentum_W
from lander_sim.physics import rotation
from lander_sim.physics.rigid_body import kinetic_energy

from .problems import KeplerTop, state

INERTIA = np.array([1.0, 2.0, 3.0])


def _run(name: str, n: int = 2000, **opts):
    dyn = KeplerTop(tuple(INERTIA), translation=False)
    y = state(np.zeros(3), np.zeros(3), rotation.axis_angle_to_quat(np.array([0.0, 1.0, 1.0]), 0.3), [0.01, 2.0, 0.01])
    mon = HealthMonitor(energy=lambda y: kinetic_energy(*INERTIA, y[10:13]), angular_momentum_W=lambda y: angular_momentum_W(y, INERTIA))
    integ = make(name, **opts)
    mon.observe(y)
    for i in range(n):
        integ.step(dyn, i * 0.01, y, 0.01)
        mon.observe(y)
    return mon.report(integ)


def test_report_shows_what_each_method_conserves() -> None:
    geo = _run("geometric")
    # DLM: |L_W| exact to round-off (1e-12 after 2000 steps x 5 substeps), |q| = 1 by construction,
    # energy error O((|w| dt)^2) = 4e-4 at most.
    assert geo.momentum_drift < 1e-12 and geo.quat_norm_error < 1e-13 and geo.energy_drift < 4e-4
    assert geo.accepted is None and geo.samples == 2001
    raw = _run("verlet", renormalise=False)
    # Without renormalisation Verlet's |q| grows by |w|^2 dt^2 / 8 per step: 2000 steps at
    # |w| = 2 rad/s give ~2e-3 or more; the report must show it, not hide it.
    assert raw.quat_norm_error > 1e-3


def test_adaptive_counters_are_reported() -> None:
    rep = _run("adaptive", n=200, rtol=1e-9, atol=1e-9)
    assert rep.accepted >= 200 and rep.rejected is not None and 0.0 < rep.error_estimate <= 1.0
    assert rep.energy_drift < 1e-7  # 200 steps of local error <= 1e-9 each, relative energy ~1
    assert any("adaptive steps" in line for line in rep.lines())


def test_a_run_that_blew_up_reports_infinite_drift_not_a_hidden_nan() -> None:
    mon = HealthMonitor(energy=lambda y: kinetic_energy(*INERTIA, y[10:13]))
    y = state(np.zeros(3), np.zeros(3), [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    mon.observe(y)
    y[10:13] = np.nan
    mon.observe(y)
    assert mon.report().energy_drift == float("inf")


def test_the_global_error_bound_is_reported_in_global_mode_only() -> None:
    assert _run("adaptive", n=20, rtol=1e-9, atol=1e-9).global_error_bound is None
    rep = _run("adaptive", n=20, rtol=1e-9, atol=1e-9, error_control="global")
    # Each 0.01 s call met its tolerance, so the largest bound over the calls is within it.
    assert rep.global_error_bound is not None and 0.0 < rep.global_error_bound <= 1.0
    assert any("global error" in line for line in rep.lines())
