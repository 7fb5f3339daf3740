"""Translational + attitude model (lander_autopilot/design/translational.py): derivation and controllability."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_autopilot.design.controllability import controllability
from lander_autopilot.design.gains import lqr, place_poles
from lander_autopilot.design.numerical import _dynamics, linearise
from lander_autopilot.design.translational import FULL_STATES, full_model, local_frame
from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.rotation import euler_rates_matrix
from lander_sim.physics.state import N_STATE
from lander_sim.scenes.vehicles import lander

FUEL = 100.0
ALT = 500.0
PSI, WZ = FULL_STATES.index("psi"), FULL_STATES.index("wz")


def _core_rhs(vehicle, fuel):
    """Nonlinear f(x, u) of the 12 local-frame states from the simulator core (inverse-square gravity,
    thrusters, Euler's equations, eq 5 kinematics): an independent derivation of the linear model."""
    dyn = _dynamics(vehicle, gravity=True)
    r0 = np.array([0.0, -(MARS_RADIUS + ALT), 0.0])
    L = local_frame(r0)  # rows east, north, up; fixed at the linearisation point
    y = np.zeros(N_STATE)
    y[13] = fuel
    acc = np.zeros(6)

    def f(x, u):
        y[0:3] = r0 + L.T @ (x[0:3] - np.array([0.0, 0.0, ALT]))
        y[3:6] = L.T @ x[3:6]
        y[6:9] = x[6:9]
        y[10:13] = x[9:12]
        dyn.inputs.throttles = np.asarray(u, dtype=float)
        dyn.accelerations(0.0, y, acc)
        return np.concatenate((x[3:6], L @ acc[0:3], euler_rates_matrix(x[6:9]) @ x[9:12], acc[3:6]))

    return f


@pytest.mark.parametrize("layout", ["canted", "standard"])
def test_full_model_matches_finite_differences_of_the_core(layout):
    v = lander(layout)
    m = full_model(v, FUEL, ALT)
    x_e = np.zeros(12)
    x_e[2] = ALT
    x_e[6:9] = (0.0, math.pi / 2, 0.0)
    u_e = np.full(v.n_thrusters, m.t_e)
    np.testing.assert_allclose(_core_rhs(v, FUEL)(x_e, u_e), 0.0, atol=1e-9)  # a true equilibrium
    A_fd, B_fd = linearise(_core_rhs(v, FUEL), x_e, u_e, h_x=np.r_[[1.0] * 3, [1e-3] * 3, [1e-5] * 6], h_u=1e-5)
    # The model drops the gravity gradient (eq 16's flat-ground choice): 2GM/z^3 vertically,
    # -GM/z^3 horizontally. Put them back, then the rest agrees to finite-difference accuracy.
    z = MARS_RADIUS + ALT
    A = m.A.copy()
    A[3, 0] = A[4, 1] = -GM_MARS / z**3
    A[5, 2] = 2.0 * GM_MARS / z**3
    np.testing.assert_allclose(A_fd, A, atol=1e-8)
    np.testing.assert_allclose(B_fd, m.B, atol=1e-8)


def test_canted_full_model_is_controllable_as_the_closed_form_says():
    # A is nilpotent (every block of the hover model is), so by the PBH test (eigenvalue 0 only)
    # the pair is controllable iff rank [A B] = 12. [A B] reaches p (from v), E (from w), v_E, v_N
    # (tilt), and B's rows (v_U, wx, wy, wz) form the 4x4 matrix [F_U; Q] / (m, I): full rank for
    # the canted layout (its z torques are nonzero), so the closed form says rank 12, nothing
    # uncontrollable.
    v = lander("canted")
    m = full_model(v, FUEL, ALT)
    assert np.abs(np.linalg.matrix_power(m.A, 12)).max() == 0.0
    sub = m.B[[5, 9, 10, 11], :]
    assert abs(np.linalg.det(sub)) > 1e-6 * np.abs(sub).max() ** 4
    assert np.linalg.matrix_rank(np.hstack((m.A, m.B))) == 12
    c = controllability(m.A, m.B)
    assert c.rank == 12 and c.uncontrollable.shape == (12, 0)


def test_vertical_full_model_leaves_exactly_psi_and_wz_uncontrollable():
    # Vertical exhausts make no z torque, and psi (rotation about body z at upright) does not tilt
    # the thrust (row psi of the tilt matrix is zero): e_wz is a left null vector of [A B], and
    # e_psi^T A^k B = 0 for all k. Closed form: rank 10, left null space span{e_psi, e_wz}.
    m = full_model(lander("standard"), FUEL, ALT)
    c = controllability(m.A, m.B)
    assert c.rank == 10
    expected = np.zeros((12, 2))
    expected[PSI, 0] = expected[WZ, 1] = 1.0
    np.testing.assert_allclose(c.uncontrollable @ c.uncontrollable.T, expected @ expected.T, atol=1e-12)


def test_full_model_gains_by_placement_and_lqr_close_the_loop():
    v = lander("canted")
    m = full_model(v, FUEL, ALT)
    poles = [-0.4, -0.45, -0.5, -0.55, -0.6, -0.9, -1.0, -1.05, -1.1, -1.15, -1.2, -1.3]
    d = place_poles(m.A, m.B, poles)
    np.testing.assert_allclose(np.sort(d.poles.real), np.sort(poles), atol=1e-6)
    np.testing.assert_allclose(d.poles.imag, 0.0, atol=1e-6)
    q = lqr(m.A, m.B, np.eye(12), 10.0 * np.eye(4))
    assert np.all(q.poles.real < 0.0)


def test_local_frame_is_enu_and_right_handed():
    L = local_frame(np.array([0.0, -5.0, 0.0]))
    np.testing.assert_allclose(L, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-15)
    for r in (np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 7.0])):  # generic point and a pole
        L = local_frame(r)
        np.testing.assert_allclose(L @ L.T, np.eye(3), atol=1e-15)
        np.testing.assert_allclose(np.cross(L[0], L[1]), L[2], atol=1e-15)
        np.testing.assert_allclose(L[2], r / np.linalg.norm(r), atol=1e-15)


@pytest.mark.parametrize("layout, rank", [("canted", 12), ("standard", 10)])
def test_design_report_gives_the_full_models_rank_and_directions(layout, rank):
    from lander_autopilot.design.report import design_report, format_report

    rep = design_report(lander(layout), FUEL, ALT)
    t = rep["translational"]
    assert t["frame"] == "local_enu" and t["states"] == list(FULL_STATES)
    assert (t["controllability_rank"], t["n_states"]) == (rank, 12)
    expected = [] if rank == 12 else [[1.0 if i == PSI else 0.0 for i in range(12)], [1.0 if i == WZ else 0.0 for i in range(12)]]
    np.testing.assert_allclose(np.abs(np.array(t["uncontrollable_basis"]).reshape(-1, 12)), np.array(expected).reshape(-1, 12), atol=1e-12)
    assert ("error" in t["lqr"]) == (rank < 12)  # LQR needs a stabilisable pair
    assert f"controllability matrix rank = {rank} of 12" in format_report(rep)
