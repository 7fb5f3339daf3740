"""Design library: linear models (control reference eq 9-28), controllability (eq 6), placement, LQR."""
from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np
import pytest

from lander_autopilot.design import DesignError
from lander_autopilot.design.altitude import altitude_model, balanced_thrust, hover_throttle, vertical_thrust
from lander_autopilot.design.attitude import UPRIGHT_EULER, attitude_model, thrust_torque_matrix
from lander_autopilot.design.controllability import controllability, controllability_matrix
from lander_autopilot.design.gains import lqr, match_poles, place_on_column_space, place_poles
from lander_autopilot.design.numerical import altitude_rhs, attitude_rhs, linearise
from lander_autopilot.design.report import design_report, format_report
from lander_sim.physics.constants import GM_MARS, LANDER_MAX_THRUST, MARS_RADIUS
from lander_sim.scenes.vehicles import lander

FUEL = 100.0
PSI, WZ = 2, 5  # indices in x = [phi theta psi wx wy wz]


@pytest.fixture(scope="module")
def vertical():
    return lander("standard")


@pytest.fixture(scope="module")
def canted():
    return lander("canted")


def _projector(basis: np.ndarray) -> np.ndarray:
    return basis @ basis.T


# --- controllability ----------------------------------------------------------


@pytest.mark.parametrize("E", [UPRIGHT_EULER, (0.3, 1.0, -0.5)])
def test_vertical_thrusters_leave_rotation_about_body_z_uncontrollable(vertical, E):
    # Vertical exhausts: s_i = p_i x (0,0,-1) has no z part, so no thruster makes a z torque:
    # wz is unreachable. The reachable angle changes are J e_x and J e_y (eq 5, rotation about
    # body x and y); their common normal is the row of J^-1 (eq 4) that gives wz:
    # wz = cos(theta) phi' + psi'. So the left null space of P is exactly
    # span{(cos theta, 0, 1, 0, 0, 0), e_wz}: at upright (theta = pi/2) pure psi and wz.
    # The basis comes from an SVD of a matrix with O(1) entries: exact to ~1e-15, so 1e-12.
    m = attitude_model(vertical, FUEL, E)
    c = controllability(m.A, m.B)
    assert c.rank == 4
    expected = np.zeros((6, 2))
    expected[[0, PSI], 0] = np.array([math.cos(E[1]), 1.0]) / math.hypot(math.cos(E[1]), 1.0)
    expected[WZ, 1] = 1.0
    np.testing.assert_allclose(_projector(c.uncontrollable), _projector(expected), atol=1e-12)
    # Left null space: P^T w = 0 for every basis vector (section 3.4).
    assert np.abs(c.P.T @ c.uncontrollable).max() < 1e-12 * np.abs(c.P).max()


def test_canted_thrusters_make_attitude_fully_controllable(canted):
    m = attitude_model(canted, FUEL)
    c = controllability(m.A, m.B)
    assert c.rank == 6 and c.controllable
    assert c.uncontrollable.shape == (6, 0)
    # Margin: the smallest singular value is far above the rank tolerance (not a borderline call).
    assert c.singular_values[-1] > 1e6 * c.tol


def test_controllability_matrix_is_eq_6():
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [2.0]])
    np.testing.assert_array_equal(controllability_matrix(A, B), np.hstack([B, A @ B]))
    with pytest.raises(DesignError, match="B must have 2 rows"):
        controllability_matrix(A, np.ones((3, 1)))


# --- models ------------------------------------------------------------------


def test_vertical_thrust_of_canted_layout_is_the_cosine_share(canted, vertical):
    # Each canted exhaust is (+-0.25, 0, -1)/|.|: its vertical share is 1/sqrt(1.0625).
    assert vertical_thrust(vertical) == pytest.approx(4 * LANDER_MAX_THRUST, rel=1e-15)
    assert vertical_thrust(canted) == pytest.approx(4 * LANDER_MAX_THRUST / math.sqrt(1.0625), rel=1e-15)


def test_balanced_thrust_is_the_most_the_thrusters_give_with_no_torque(canted):
    # The nominal canted layout is symmetric: every thruster flat out makes no torque.
    T, flow = balanced_thrust(canted)
    assert T == pytest.approx(vertical_thrust(canted), rel=1e-9)
    assert flow == pytest.approx(sum(t.fuel_rate for t in canted.thrusters), rel=1e-9)
    # One thruster 3 % weak and another canted 0.5 degrees off: full throttle on all four is a torque.
    # With four thrusters the torque map (rank 3) has one null vector, the only torque-free mix
    # (found here by SVD, independently of the linear programme): scaled so that its largest
    # throttle is 1, it gives the most thrust with no torque.
    ts = list(canted.thrusters)
    ts[0] = dataclasses.replace(ts[0], max_thrust=0.97 * ts[0].max_thrust)
    c, s = math.cos(0.0087), math.sin(0.0087)
    d = ts[2].direction_B
    ts[2] = dataclasses.replace(ts[2], direction_B=np.array([c * d[0] - s * d[2], d[1], s * d[0] + c * d[2]]))
    off = dataclasses.replace(canted, thrusters=tuple(ts))
    M = thrust_torque_matrix(off)
    n = np.linalg.svd(M)[2][-1]
    n = n / n[np.argmax(np.abs(n))]
    axial = np.array([-t.direction_B[2] * t.max_thrust for t in ts])
    T, flow = balanced_thrust(off)
    assert T == pytest.approx(float(axial @ n), rel=1e-9)
    assert flow == pytest.approx(sum(t.fuel_rate * x for t, x in zip(ts, n)), rel=1e-9)
    assert T < vertical_thrust(off) * 0.99  # not the nameplate sum: ~3 % of it is lost to the balance


@pytest.mark.parametrize("layout", ["standard", "canted"])
def test_hover_throttle_cancels_gravity_in_the_core_model(layout):
    # Eq 14: at t_e the core's own z'' (gravity + thrusters) vanishes; rounding only (|g| ~ 3.7).
    v = lander(layout)
    z = MARS_RADIUS + 500.0
    f = altitude_rhs(v, FUEL)
    zdd = f(np.array([z, 0.0]), np.array([hover_throttle(v, FUEL, z)]))[1]
    assert abs(zdd) < 1e-13


def test_altitude_model_is_eq_16_and_fd_finds_eq_15(canted):
    m = altitude_model(canted, FUEL, 500.0)
    np.testing.assert_array_equal(m.A, [[0.0, 1.0], [0.0, 0.0]])
    assert m.B[1, 0] == pytest.approx(vertical_thrust(canted) / canted.mass(FUEL), rel=1e-15)
    # FD of the core's nonlinear model with steps h_z = 10 m, h_v = 1e-3 m/s, h_t = 1e-5:
    # -GM/z^2 has relative third derivative ~ (h/z)^2 ~ 1e-11 and z'' is linear in t and z',
    # so the FD equals eq 15 (with 2GM/z^3) to rounding: eps |g| / h_z ~ 4e-17 on a 2.2e-6 entry.
    g = altitude_model(canted, FUEL, 500.0, gravity_gradient=True)
    A, B = linearise(altitude_rhs(canted, FUEL), [g.z_e, 0.0], [g.t_e], h_x=[10.0, 1e-3], h_u=1e-5)
    np.testing.assert_allclose(A, g.A, rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(B, g.B, rtol=1e-9)
    assert g.A[1, 0] == pytest.approx(2 * GM_MARS / g.z_e**3, rel=1e-15)


@pytest.mark.parametrize(
    "E, w, u",
    [
        (UPRIGHT_EULER, (0.0, 0.0, 0.0), (0.0,) * 4),  # the design point
        ((0.3, 1.2, -0.4), (0.1, -0.2, 0.3), (0.3,) * 4),  # exercises every omega term of eq 23 and 25
    ],
)
@pytest.mark.parametrize("layout", ["standard", "canted"])
def test_analytic_attitude_model_matches_finite_differences(layout, E, w, u):
    # Central differences with h = 1e-5: truncation h^2 |f'''| / 6 with |f'''| = O(10) at
    # sin(theta) ~ 0.9 -> ~1e-10; rounding eps |f| / h ~ 1e-16 * 10 / 1e-5 = 1e-10. So 1e-8.
    v = lander(layout)
    m = attitude_model(v, FUEL, E, w)
    A, B = linearise(attitude_rhs(v, FUEL), np.r_[E, w], np.array(u), h_x=1e-5, h_u=1e-5)
    np.testing.assert_allclose(A, m.A, atol=1e-8)
    np.testing.assert_allclose(B, m.B, atol=1e-8)


def test_finite_difference_error_shrinks_as_h_squared(canted):
    # Central differences are O(h^2): halving h divides the error by 4 (while truncation
    # dominates rounding: h = 0.1 -> 0.05 gives errors ~1e-3, far above eps / h).
    E, w = np.array([0.3, 1.2, -0.4]), np.array([0.1, -0.2, 0.3])
    exact = attitude_model(canted, FUEL, E, w).A
    f = attitude_rhs(canted, FUEL)
    err = [np.abs(linearise(f, np.r_[E, w], np.zeros(4), h_x=h)[0] - exact).max() for h in (0.1, 0.05)]
    assert err[0] / err[1] == pytest.approx(4.0, rel=0.1)


def test_attitude_model_refuses_the_euler_singularity(canted):
    with pytest.raises(DesignError, match="singularity"):
        attitude_model(canted, FUEL, (0.0, 0.0, 0.0))


# --- gains -------------------------------------------------------------------


def test_altitude_placement_matches_eq_20_closed_form(canted):
    # Eq 19-20: poles p1, p2 need T_v k1/m = p1 p2 and T_v k2/m = -(p1 + p2).
    m = altitude_model(canted, FUEL, 500.0)
    d = place_poles(m.A, m.B, [-0.9, -1.1])
    assert d.method == "place"
    b = m.T_v / m.mass
    np.testing.assert_allclose(d.K, [[0.99 / b, 2.0 / b]], rtol=1e-12)
    assert match_poles(d.requested, d.poles) < 1e-6


@pytest.mark.parametrize(
    "poles",
    [
        (-1.0,) * 6,  # the seed's choice: repeated 6 times > rank B = 3, python-control place refuses
        (-0.5, -1.0, -1.5, -2.0, -2.5, -3.0),
        # a complex pair with a repeated real pole: where SB01BD misses (on some machines it returns
        # gains of 1e45, poles at 1e30, with only a SlycotResultWarning) the placement is redone
        (-1 + 0.5j, -1 - 0.5j, -2.0, -2.0, -0.7, -3.0),
    ],
)
def test_attitude_placement_meets_requested_poles_to_1e6(canted, poles):
    # B is 6x4 of rank 3 (four throttles, three torques): control.place refuses it as it is. Repeated
    # poles of a non-derogatory placement move by O(eps^(1/k)) ~ 1e-8 for k = 2 blocks: 1e-6 has room.
    # Which of the two rank-deficient methods serves depends on SB01BD's floating point on this
    # machine; the contract is the poles met, and a fallback placement equal to the fallback's own.
    m = attitude_model(canted, FUEL)
    d = place_poles(m.A, m.B, poles)
    assert d.method in ("place_varga", "place on the column space of B")
    assert match_poles(d.requested, d.poles) < 1e-6
    if d.method == "place on the column space of B":
        np.testing.assert_array_equal(d.K, place_on_column_space(m.A, m.B, poles).K)


@pytest.mark.parametrize("poles", [(-0.5, -1.0, -1.5, -2.0, -2.5, -3.0), (-1 + 0.5j, -1 - 0.5j, -2.0, -2.0, -0.7, -3.0)])
def test_column_space_placement_meets_poles_with_the_minimum_norm_allocation(canted, poles):
    # K = V K_r with V an orthonormal basis of B's row space: K's rows lie in that space (K = V V^T K),
    # the minimum-norm throttle allocation, and the poles are met to the same 1e-6.
    m = attitude_model(canted, FUEL)
    d = place_on_column_space(m.A, m.B, poles)
    assert match_poles(d.requested, d.poles) < 1e-6
    V = np.linalg.svd(m.B)[2][:3].T
    np.testing.assert_allclose(V @ V.T @ d.K, d.K, atol=1e-9 * np.abs(d.K).max())


def test_placement_on_uncontrollable_pair_leaves_the_uncontrollable_modes(vertical):
    # Varga moves only the controllable modes; psi and wz keep their open-loop eigenvalue 0.
    m = attitude_model(vertical, FUEL)
    d = place_poles(m.A, m.B, (-1.0,) * 6)
    assert np.sum(np.abs(d.poles) < 1e-9) == 2
    assert match_poles(np.full(4, -1.0), d.poles[np.abs(d.poles) > 1e-9]) < 1e-6


def test_place_rejects_bad_pole_sets(canted):
    m = attitude_model(canted, FUEL)
    with pytest.raises(DesignError, match="need 6 poles"):
        place_poles(m.A, m.B, [-1.0] * 5)
    with pytest.raises(DesignError, match="conjugate pairs"):
        place_poles(m.A, m.B, [-1 + 1j, -1, -1, -1, -1, -1])


def test_lqr_stabilises_canted_and_fails_on_vertical(canted, vertical):
    m = attitude_model(canted, FUEL)
    d = lqr(m.A, m.B, np.eye(6), np.eye(4))
    assert np.all(d.poles.real < 0)
    mv = attitude_model(vertical, FUEL)
    with pytest.raises(DesignError, match="stabilisable"):
        lqr(mv.A, mv.B, np.eye(6), np.eye(4))
    with pytest.raises(DesignError, match=r"Q must have shape \(6, 6\)"):
        lqr(m.A, m.B, np.eye(5), np.eye(4))


# --- report and command ------------------------------------------------------


def test_report_json_has_both_models_and_rank(vertical, canted):
    rv = json.loads(json.dumps(design_report(vertical, FUEL)))
    assert rv["attitude"]["controllability_rank"] == 4
    assert len(rv["attitude"]["uncontrollable_basis"]) == 2
    assert rv["altitude"]["controllability_rank"] == 2
    assert "error" in rv["attitude"]["lqr"]
    rc = design_report(canted, FUEL)
    assert rc["attitude"]["controllability_rank"] == 6 and rc["attitude"]["uncontrollable_basis"] == []
    assert np.asarray(rc["attitude"]["placement"]["K"]).shape == (4, 6)
    text = format_report(rc)
    assert "rank = 6 of 6" in text and "place_varga" in text


def test_printed_matrices_and_poles_show_round_off_as_zero_and_never_minus_zero(vertical):
    """The vertical thrusters' attitude model: cos(pi/2) round-off in A, a pole left at ~1e-16 by
    the placement; the JSON keeps the computed values, the text shows what they mean."""
    rep = design_report(vertical, FUEL)
    A = np.asarray(rep["attitude"]["A"])
    assert 0 < np.abs(A[A != 0]).min() < 1e-12 * np.abs(A).max()  # the round-off the text must hide
    text = format_report(rep)
    tokens = text.replace(",", " ").split()
    assert "-0" not in tokens and not any("e-1" in t for t in tokens), text


def test_design_command_json_and_bad_scene(capsys):
    from lander_tools.commands import design

    p = argparse.ArgumentParser()
    design.add_arguments(p)
    assert design.run(p.parse_args(["hover-canted", "--json"])) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["attitude"]["controllability_rank"] == 6
    for pole in out["attitude"]["placement"]["closed_loop_poles"]:
        assert abs(complex(*pole) + 1.0) < 1e-6
    assert design.run(p.parse_args(["no-such-scene"])) == 2
    assert "no-such-scene" in capsys.readouterr().err
