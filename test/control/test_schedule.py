"""Gain scheduling of the vertical law over mass and drag damping: exact at the grid, second order between,
and the same numbers as python-control's gain-scheduled state feedback."""
from __future__ import annotations

import numpy as np

from lander_autopilot.design.gains import closed_loop_poles, match_poles
from lander_autopilot.design.schedule import schedule_vertical, to_iosystem, vertical_descent_model
from lander_sim.physics.constants import LANDER_MAX_THRUST

T_V = 4 * LANDER_MAX_THRUST  # standard layout: every thruster along body z
POLES = (-0.9, -1.1)


def _pole_error(sched, m, d):
    A, B = vertical_descent_model(m, d, T_V)
    return match_poles(np.array(POLES, complex), closed_loop_poles(A, B, sched.gain((m, d))))


def test_gains_place_the_poles_exactly_at_every_grid_point():
    s = schedule_vertical(T_V, np.linspace(100, 200, 3), np.linspace(0.0, 2.0, 3), POLES)
    for m, d in s.points:
        assert _pole_error(s, m, d) < 1e-9


def _charpoly_error(sched, m, d):
    """Largest error of the closed loop's characteristic-polynomial coefficients (what K sets linearly;
    the poles (-0.9, -1.1) sit close enough that they move as the square root of it)."""
    A, B = vertical_descent_model(m, d, T_V)
    return float(np.max(np.abs(np.poly(A - B @ sched.gain((m, d))) - np.poly(POLES))))


def _centres(ms, ds):
    return [((a + b) / 2, (c + d) / 2) for a, b in zip(ms[:-1], ms[1:]) for c, d in zip(ds[:-1], ds[1:])]


def test_interpolation_error_is_second_order_in_the_grid_step():
    # The exact gain is bilinear in (m, d) (k2 = (-(p1 + p2) - d) m / T_v); linear interpolation on
    # a cell's triangles misses it by the m*d term, largest on the cell's diagonal, of size
    # h_m h_d / 4: half the step both ways, a quarter the error in the characteristic polynomial
    # (which K sets linearly; B's 1/m gives cells of different masses different weights: 3x, not 4x).
    grids = [(np.linspace(100, 200, k), np.linspace(0.0, 2.0, k)) for k in (3, 5)]
    coarse, fine = (schedule_vertical(T_V, ms, ds, POLES) for ms, ds in grids)
    e_coarse = max(_charpoly_error(coarse, m, d) for m, d in _centres(*grids[0]))
    e_fine = max(_charpoly_error(fine, m, d) for m, d in _centres(*grids[1]))
    assert 0 < e_fine < e_coarse / 3
    # and scheduling matters: one gain designed at the grid's centre misses far more at a corner
    fixed = schedule_vertical(T_V, [149.0, 151.0], [0.99, 1.01], POLES)  # ~ the gain at (150, 1)
    assert _charpoly_error(fixed, 100.0, 2.0) > 10 * e_coarse


def test_same_gain_as_python_controls_gain_scheduled_state_feedback():
    s = schedule_vertical(T_V, np.linspace(100, 200, 4), np.linspace(0.0, 2.0, 3), POLES)
    ctrl = to_iosystem(s, 2)
    rng = np.random.default_rng(7)
    for _ in range(25):
        # inside the hull and a little outside it (nearest point's gain in both implementations)
        mu = (rng.uniform(90, 210), rng.uniform(-0.1, 2.1))
        e = rng.normal(size=2)
        n = 2 + 2
        inputs = np.r_[np.zeros(n), 0.0, e, mu]  # x_d = 0, u_d = 0, x = (e, mu)
        u_pc = np.asarray(ctrl.output(0.0, [], inputs)).ravel()
        np.testing.assert_allclose(u_pc, -s.gain(mu) @ e, rtol=1e-12, atol=1e-12)


def test_descent_rate_schedule_flown_by_the_deorbit_law():
    """The velocity loop of the de-orbit law's braking curve: exact pole at the grid points, the
    interpolation's miss second order (the exact gain (-p - d) m / T_v has an m*d term), and the
    law reads it (``DescentToAltitude.rate_gain`` in acceleration units, T_v K / m = -p - d)."""
    from lander_autopilot.controllers.deorbit import DeorbitController
    from lander_autopilot.design.schedule import descent_rate_model, schedule_descent_rate
    from lander_sim.scenes import load_scene

    pole = -2.0
    s = schedule_descent_rate(T_V, np.linspace(100, 200, 3), np.linspace(0.0, 1.0, 3), pole)
    for m, d in s.points:
        A, B = descent_rate_model(m, d, T_V)
        assert abs(float((A - B @ s.gain((m, d)))[0, 0]) - pole) < 1e-9

    def miss(sched, m, d):
        A, B = descent_rate_model(m, d, T_V)
        return abs(float((A - B @ sched.gain((m, d)))[0, 0]) - pole)

    grids = [(np.linspace(100, 200, k), np.linspace(0.0, 1.0, k)) for k in (3, 5)]
    coarse, fine = (schedule_descent_rate(T_V, ms, ds, pole) for ms, ds in grids)
    e_coarse = max(miss(coarse, m, d) for m, d in _centres(*grids[0]))
    e_fine = max(miss(fine, m, d) for m, d in _centres(*grids[1]))
    assert 0 < e_fine < e_coarse / 3

    sc = load_scene("deorbit")
    law = DeorbitController(sc.vehicle, descent_pole=pole).descent
    for mass, d in ((sc.vehicle.dry_mass + 60.0, 0.0), (sc.vehicle.dry_mass + 20.0, 0.3)):
        law.law.mass = mass
        # the law's grid is the fine one (5 x 5 over dry..full mass = 100..200 kg, 0..1 /s); its miss
        # in acceleration units, (T_v / m) dK, does not depend on T_v, and is largest at cell centres
        assert abs(law.rate_gain(d) - (-pole - d)) <= e_fine * (1 + 1e-9)
