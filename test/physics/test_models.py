"""Force and torque models one by one, against closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.physics import constants as c
from lander_sim.physics import rotation
from lander_sim.physics.models import (
    Atmosphere,
    ChuteStatus,
    ConstantForce,
    EvalContext,
    Inputs,
    InverseSquareGravity,
    MeshDrag,
    Parachute,
    SphereDrag,
    Thrusters,
    UniformGravity,
    sphere_mesh,
)
from lander_sim.scenes import vehicles


def ctx_for(y: np.ndarray, rho: float = 0.0, throttles=(), wind=(0.0, 0.0, 0.0), mass: float = 200.0) -> EvalContext:
    ctx = EvalContext(inputs=Inputs(np.array(throttles, dtype=float), np.array(wind, dtype=float)))
    ctx.y, ctx.R, ctx.rho, ctx.mass = y, rotation.quat_to_matrix(y[6:10]), rho, mass
    return ctx


def state(v=(0.0, 0.0, 0.0), q=(1.0, 0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0), fuel=100.0, r=(c.MARS_RADIUS + 1000, 0, 0)) -> np.ndarray:
    return np.array([*r, *v, *q, *w, fuel], dtype=float)


def add(model, ctx):
    fW, fB, qB = np.zeros(3), np.zeros(3), np.zeros(3)
    model.add(ctx, fW, fB, qB)
    return fW, fB, qB


def test_constants_match_the_original_program():
    assert math.isclose(c.GM_MARS, 6.673e-11 * 6.42e23)
    assert math.isclose(c.LANDER_MAX_THRUST, 373.7, rel_tol=1e-3)  # "about 373.7 N"


def test_inverse_square_gravity_and_uniform_gravity():
    y = state(r=(3e6, 4e6, 0.0))
    fW, fB, qB = add(InverseSquareGravity(), ctx_for(y, mass=2.0))
    assert np.allclose(fW, -c.GM_MARS * 2.0 / 5e6**2 * np.array([0.6, 0.8, 0.0]), rtol=1e-14)
    assert not fB.any() and not qB.any()
    fW, _, _ = add(UniformGravity(np.array([0, 0, -9.81])), ctx_for(y, mass=2.0))
    assert np.allclose(fW, [0, 0, -19.62])


def test_atmosphere_density_profile():
    a = Atmosphere()
    assert a.density(0.0) == 0.017
    assert math.isclose(a.density(11000.0), 0.017 / math.e)
    assert a.density(200e3) > 0.0 and a.density(200e3 + 1.0) == 0.0


def test_sphere_drag_is_quadratic_along_the_relative_air_velocity():
    y = state(v=(10.0, -20.0, 5.0))
    wind = (3.0, 1.0, 0.0)
    fW, _, qB = add(SphereDrag(), ctx_for(y, rho=0.01, wind=wind))
    W = np.array(wind) - y[3:6]
    assert np.allclose(fW, 0.5 * 0.01 * 1.0 * math.pi * np.linalg.norm(W) * W, rtol=1e-14)
    assert not qB.any()
    assert not add(SphereDrag(), ctx_for(y, rho=0.0))[0].any()  # vacuum: nothing


def test_mesh_drag_converges_to_the_sphere_model_at_second_order():
    # Newtonian pressure on a sphere of radius L integrates exactly to Cd = 1 on pi L^2
    # (module docstring); the midpoint panel sums converge as h^2: halving h quarters the error.
    W, rho = np.array([30.0, -50.0, 80.0]), 0.01
    ref = 0.5 * rho * math.pi * np.linalg.norm(W) * W
    errs = []
    for n in (12, 24):
        m = MeshDrag(*sphere_mesh(1.0, np.zeros(3), n, 2 * n), skin_friction=0.0)
        F = m.forces_B(rho, W, np.zeros(3))
        errs.append(np.linalg.norm(F.sum(0) - ref) / np.linalg.norm(ref))
        # Only the panels facing the flow are loaded (about half of them).
        loaded = np.any(F != 0.0, axis=1)
        assert np.all((m.normals_B[loaded] @ W) < 0.0)
        assert abs(loaded.mean() - 0.5) < 0.05
    assert errs[1] < 2e-3
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_mesh_drag_torque_is_sum_of_pos_cross_force_and_world_force_matches():
    m = MeshDrag(*sphere_mesh(1.0, np.array([0.0, 0.0, 0.4]), 12, 24), skin_friction=0.01)
    q = rotation.quat_normalise(np.array([0.9, 0.2, -0.3, 0.1]))
    y = state(v=(40.0, 10.0, -60.0), q=q, w=(0.3, -0.2, 0.5))
    ctx = ctx_for(y, rho=0.015, wind=(5.0, 0.0, 0.0))
    _, fB, qB = add(m, ctx)
    F = m.forces_B(0.015, ctx.R @ (np.array([5.0, 0, 0]) - y[3:6]), y[10:13])
    assert np.allclose(fB, F.sum(0), rtol=1e-12)
    assert np.allclose(qB, np.cross(m.centres_B, F).sum(0), rtol=1e-12)
    # Centre of the shape 0.4 m above the centre of mass: a nonzero aerodynamic torque.
    assert np.linalg.norm(qB) > 1e-3 * np.linalg.norm(fB)


def test_thrusters_force_torque_fuel_disabled_and_empty_tank():
    veh = vehicles.lander(disabled=(2,))
    th = Thrusters(veh)
    t = np.array([0.1, 0.2, 0.9, 0.4])
    fW, fB, qB = add(th, ctx_for(state(), throttles=t))
    on = np.array([1, 1, 0, 1.0])
    F_i = [-tr.direction_B * ti * tr.max_thrust * e for tr, ti, e in zip(veh.thrusters, t, on)]
    assert np.allclose(fB, np.sum(F_i, axis=0), rtol=1e-14)
    assert np.allclose(qB, np.sum([np.cross(tr.position_B, f) for tr, f in zip(veh.thrusters, F_i)], axis=0), atol=1e-12)
    assert not fW.any()
    assert math.isclose(th.fuel_rate(state(), t), -0.5 * (0.1 + 0.2 + 0.4))
    # No fuel, no thrust and no burn.
    _, fB0, qB0 = add(th, ctx_for(state(fuel=0.0), throttles=t))
    assert not fB0.any() and not qB0.any() and th.fuel_rate(state(fuel=0.0), t) == 0.0


def test_canted_thrusters_of_seed_2_and_lander_geometry():
    std, cant = vehicles.lander(), vehicles.lander("canted")
    for tr in std.thrusters:
        assert np.allclose(np.abs(tr.position_B), [0.45, 0.45, 0.2]) and np.allclose(tr.direction_B, [0, 0, -1])
    for tr in cant.thrusters:
        assert np.allclose(tr.direction_B, np.array([math.copysign(0.25, tr.position_B[0]), 0, -1]) / math.hypot(0.25, 1))
    assert np.allclose(std.inertia(100.0), [90.0, 90.0, 60.0])
    with pytest.raises(ValueError, match="thrusters must be one of"):
        vehicles.lander("sideways")


def test_parachute_drag_torque_and_deploy_rules():
    p = Parachute()
    y = state(v=(0.0, 0.0, -50.0), w=(0.0, 0.0, 0.0))
    ctx = ctx_for(y, rho=0.01)
    assert not any(a.any() for a in add(p, ctx))  # packed: no force
    assert p.deploy(speed=50.0, inside_atmosphere=True) is ChuteStatus.DEPLOYED
    _, fB, qB = add(p, ctx)
    assert np.allclose(fB, [0, 0, 0.5 * 0.01 * 2.0 * math.pi * 9.0 * 50.0**2])
    assert np.allclose(qB, np.cross([0, 0, 0.5], fB))  # along the arm: zero
    assert math.isclose(p.drag_magnitude(ctx), np.linalg.norm(fB))
    q = Parachute()
    assert q.deploy(speed=600.0, inside_atmosphere=True) is ChuteStatus.LOST
    assert Parachute().deploy(speed=600.0, inside_atmosphere=False) is ChuteStatus.DEPLOYED


def test_constant_force_torque_and_potential():
    q = rotation.axis_angle_to_quat(np.array([1.0, 0, 0]), 0.7)
    y = state(q=q, r=(0, 0, 0))
    cf = ConstantForce(np.array([0, 0, -10.0]), np.array([0, 0, 1.0]))
    fW, _, qB = add(cf, ctx_for(y))
    R = rotation.quat_to_matrix(q)
    assert np.allclose(qB, np.cross([0, 0, 1.0], R @ [0, 0, -10.0]))
    assert np.allclose(fW, [0, 0, -10])
    # Potential = 10 * height of the point of action.
    assert math.isclose(cf.potential(y[0:3], R, 1.0), 10.0 * (R.T @ [0, 0, 1.0])[2])
