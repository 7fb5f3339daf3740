"""The convex fuel-optimal descent (lossless convexification) against closed forms and its own constraints."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_autopilot.guidance.fuel_optimal import (
    DescentLimits,
    DescentProblem,
    GuidanceError,
    solve,
    vertical_bang_bang,
)
from lander_sim.physics.constants import LANDER_DRY_MASS, LANDER_FUEL_RATE, LANDER_MAX_THRUST, SURFACE_GRAVITY

# The lander as a point mass: four thrusters along body z (standard layout), flat out together.
LIMITS = DescentLimits(rho_max=4 * LANDER_MAX_THRUST, alpha=LANDER_FUEL_RATE / LANDER_MAX_THRUST,
                       dry_mass=LANDER_DRY_MASS)


def _vertical(h: float, v: float, m: float = 180.0, limits: DescentLimits = LIMITS) -> DescentProblem:
    return DescentProblem(position_L=[0.0, 0.0, h], velocity_L=[0.0, 0.0, v], mass=m,
                          gravity=SURFACE_GRAVITY, limits=limits)


@pytest.mark.parametrize(("h", "v"), [(500.0, -40.0), (300.0, 0.0)])
def test_vertical_descent_matches_the_bang_bang_optimum(h, v):
    fuel, tf = vertical_bang_bang(h, v, 180.0, SURFACE_GRAVITY, LIMITS)
    coarse = solve(_vertical(h, v), steps=40)
    fine = solve(_vertical(h, v), steps=80)
    # Piecewise-constant acceleration is a subset of all thrust histories: the discrete optimum can
    # never beat the continuous one (solver tolerance 1e-8 relative aside).
    assert coarse.fuel >= fuel * (1 - 1e-8) and fine.fuel >= fuel * (1 - 1e-8)
    # Linear interpolation of u = T/m between nodes follows the burn's smooth rise of T/m to O(dt^2);
    # what is left is the one switch, inside a step. Measured 1e-5 to 3e-4 at 40 steps: the
    # issue's 1e-3 holds at 40 steps, and halving the step never makes it worse.
    assert (coarse.fuel - fuel) / fuel < 1e-3
    assert fine.fuel <= coarse.fuel * (1 + 1e-9)
    assert fine.final_time == pytest.approx(tf, rel=1e-3)
    # The thrust is bang-bang: off, then flat out (every step but the one holding the switch).
    frac = fine.thrust_magnitude / LIMITS.rho_max
    assert np.sum((frac > 1e-2) & (frac < 1 - 1e-2)) <= 2


def test_an_end_tolerance_is_the_optimum_to_its_nearest_edge():
    """``end_band``: a fall from above ends at rest on the band's top edge, the closed-form bang-bang
    to that altitude (to the discretisation's 1e-3); ``end_speed``: it ends at the target still falling at
    that speed, for less fuel; 0 for both is the problem at rest on the target."""
    h, v, band, speed = 500.0, -40.0, 2.0, 0.2
    exact = solve(_vertical(h, v), steps=60)
    edge_fuel, edge_tf = vertical_bang_bang(h - band, v, 180.0, SURFACE_GRAVITY, LIMITS)
    banded = solve(dataclasses.replace(_vertical(h, v), end_band=band), steps=60)
    assert banded.fuel == pytest.approx(edge_fuel, rel=1e-3) and banded.fuel < exact.fuel
    # an inequality the interior-point solver meets from inside, to ~1e-5
    assert banded.position_L[-1, 2] == pytest.approx(band, abs=1e-4) and np.allclose(banded.velocity_L[-1], 0.0, atol=1e-6)
    slow = solve(dataclasses.replace(_vertical(h, v), end_speed=speed), steps=60)
    assert slow.velocity_L[-1, 2] == pytest.approx(-speed, abs=1e-4) and slow.fuel < exact.fuel
    assert solve(dataclasses.replace(_vertical(h, v), end_band=0.0, end_speed=0.0), steps=60).fuel == exact.fuel
    with pytest.raises(GuidanceError, match="end_band"):
        dataclasses.replace(_vertical(h, v), end_band=-1.0)


def test_solution_keeps_every_constraint_and_ends_at_rest_on_target():
    lim = DescentLimits(rho_max=LIMITS.rho_max, alpha=LIMITS.alpha, dry_mass=LIMITS.dry_mass,
                        max_tilt=math.radians(30), glide_slope=math.radians(10))
    p = DescentProblem(position_L=[400.0, -150.0, 1200.0], velocity_L=[-20.0, 10.0, -45.0], mass=190.0,
                       gravity=SURFACE_GRAVITY, limits=lim, target_L=[0.0, 0.0, 500.0])
    sol = solve(p, steps=60)
    np.testing.assert_allclose(sol.position_L[-1], [0, 0, 500], atol=1e-5)
    np.testing.assert_allclose(sol.velocity_L[-1], 0, atol=1e-6)
    T = sol.thrust_L
    mag = np.linalg.norm(T, axis=1)
    # Lossless: |u| = sigma at the optimum, so the true thrust magnitude keeps the true bound
    # (tangent below the convex rho e^-z: never above rho_max).
    assert np.all(mag <= lim.rho_max * (1 + 1e-6))
    tilt = np.arccos(np.clip(T[:, 2] / np.maximum(mag, 1e-12), -1, 1))
    assert np.all(tilt[mag > 1.0] <= lim.max_tilt + 1e-6)
    rel = sol.position_L - p.target_L
    assert np.all(np.linalg.norm(rel[:, :2], axis=1) * math.tan(lim.glide_slope) <= rel[:, 2] + 1e-5)
    # Mass: z = ln m falls by alpha * integral(|T| / m) (trapezoid of the linear sigma = |T|/m), and
    # the fuel reported is what the mass lost.
    sigma = mag / sol.mass
    np.testing.assert_allclose(np.diff(np.log(sol.mass)), -lim.alpha * np.diff(sol.t) * (sigma[:-1] + sigma[1:]) / 2,
                               atol=1e-6)
    assert sol.fuel == pytest.approx(p.mass - sol.mass[-1])


def test_an_unreachable_target_is_a_clear_error():
    # 60 m/s down at 50 m: not even flat out from now stops it in time.
    with pytest.raises(GuidanceError, match="no feasible descent"):
        solve(_vertical(50.0, -60.0), steps=30)


def test_bad_inputs_name_the_field():
    with pytest.raises(GuidanceError, match="position_L"):
        DescentProblem(position_L=[0, 0], velocity_L=[0, 0, 0], mass=150.0, gravity=3.7, limits=LIMITS)
    with pytest.raises(GuidanceError, match="dry mass"):
        _vertical(100.0, 0.0, m=90.0)
    with pytest.raises(GuidanceError, match="max_tilt"):
        DescentLimits(rho_max=1.0, alpha=1.0, dry_mass=1.0, max_tilt=0.0)


# --- drag (the open chute of a de-orbit descent): successive convexification -----------------------

def _chute_problem(drag: bool) -> DescentProblem:
    """Under the open chute near its terminal speed, 900 m up, to a hover at 500 m (canted lander's
    axial thrust and fuel flow; the chute's and the sphere's 1/2 Cd A, the scene's atmosphere)."""
    from lander_autopilot.guidance.fuel_optimal import DragModel
    from lander_sim.physics import constants as c

    axial = 4 * LANDER_MAX_THRUST * math.cos(math.atan(0.25))
    lim = DescentLimits(rho_max=axial, alpha=4 * LANDER_FUEL_RATE / axial, dry_mass=LANDER_DRY_MASS, max_tilt=0.7)
    k = 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2 + 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA
    model = DragModel(k, c.ATMOSPHERE_SURFACE_DENSITY, c.ATMOSPHERE_SCALE_HEIGHT) if drag else None
    return DescentProblem(position_L=[0.0, 0.0, 900.0], velocity_L=[2.0, 0.0, -34.0], mass=165.0, gravity=SURFACE_GRAVITY,
                          limits=lim, target_L=[0.0, 0.0, 500.0], free_horizontal=True, drag=model)


def _fly_open_loop(p: DescentProblem, sol) -> tuple[np.ndarray, np.ndarray]:
    """The solution's acceleration u = T/m (linear between nodes, as the programme holds it) flown on the
    true point mass with continuous drag (RK4, 50 substeps a node). Returns the final position and velocity."""
    u = sol.thrust_L / sol.mass[:, None]

    def rhs(tt, y):
        k = min(int(tt / (sol.t[1] - sol.t[0])), len(sol.t) - 2)
        w = (tt - sol.t[k]) / (sol.t[k + 1] - sol.t[k])
        uk = (1 - w) * u[k] + w * u[k + 1]
        a_d = p.drag.acceleration(y[None, :3], y[None, 3:6], np.array([y[6]]))[0]
        return np.r_[y[3:6], uk + a_d - [0, 0, p.gravity], -p.limits.alpha * np.linalg.norm(uk) * y[6]]

    y, tt = np.r_[p.position_L, p.velocity_L, p.mass], 0.0
    h = (sol.t[1] - sol.t[0]) / 50
    for _ in range(50 * (len(sol.t) - 1)):
        k1 = rhs(tt, y)
        k2 = rhs(tt + h / 2, y + h / 2 * k1)
        k3 = rhs(tt + h / 2, y + h / 2 * k2)
        k4 = rhs(tt + h, y + h * k3)
        y, tt = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), tt + h
    return y[:3], y[3:6]


@pytest.mark.parametrize("wind_L", [(0.0, 0.0, 0.0), (4.0, -2.5, 0.3)])
def test_drag_jacobian_matches_central_differences(wind_L):
    import dataclasses

    p = _chute_problem(True)
    drag = dataclasses.replace(p.drag, wind_L=wind_L)
    rng = np.random.default_rng(5)
    r, v, m = rng.uniform([-50, -50, 400], [50, 50, 900], (6, 3)), rng.normal(0, 30, (6, 3)), rng.uniform(120, 190, 6)
    # the drag acts on the airspeed v - w: the definition, to rounding
    air = v - np.array(wind_L)
    rho = drag.surface_density * np.exp(-r[:, 2] / drag.scale_height)
    np.testing.assert_allclose(drag.acceleration(r, v, m),
                               -(drag.k * rho / m * np.linalg.norm(air, axis=1))[:, None] * air, rtol=1e-14)
    p = dataclasses.replace(p, drag=drag)
    J = p.drag.jacobian(r, v, m)
    h = 1e-4
    for j in range(3):
        dv = np.zeros(3)
        dv[j] = h
        fd = (p.drag.acceleration(r, v + dv, m) - p.drag.acceleration(r, v - dv, m)) / (2 * h)
        # central differences err by ~h^2 (k rho / m) / |v| ~ 1e-8 x 1e-4: far under 1e-9
        np.testing.assert_allclose(J[:, :, j], fd, atol=1e-9)


@pytest.mark.slow  # about 15 s of solves (45 s on the shared machine)
def test_drag_optimum_is_drag_consistent_to_second_order_and_cheaper_than_without():
    from lander_autopilot.guidance.fuel_optimal import solve_fixed_time

    with_drag, without = _chute_problem(True), _chute_problem(False)
    free = solve(without, steps=30, t_tol=1e-3)
    # The chute's drag (about the weight at this speed) is a free brake: the optimum with it costs
    # less than the drag-free optimum from the same state, by far.
    sol = solve(with_drag, steps=30, t_tol=1e-3)
    assert sol.fuel < 0.9 * free.fuel
    # Flown open loop on the true point mass (continuous drag), the thrust history arrives at rest
    # at 500 m up to the programme's discretisation (trapezoidal drag, O(dt^2)): halving the step
    # cuts the miss by about 4 (at least 3 here), so the drag the programme used is the real one.
    # (At 1.1 times the optimal final time: under the chute the optimum is the latest full-thrust
    # burn, on the edge of feasibility, where a coarser grid may find none.)
    misses = []
    for n in (20, 40):
        s = solve_fixed_time(with_drag, 1.1 * sol.final_time, steps=n)
        assert s is not None
        r, v = _fly_open_loop(with_drag, s)
        print(f"steps {n}: altitude miss {r[2] - 500.0:+.4f} m, speed {np.linalg.norm(v):.5f} m/s")
        misses.append(abs(r[2] - 500.0) + s.final_time * float(np.linalg.norm(v)))
    assert misses[1] < misses[0] / 3, misses
