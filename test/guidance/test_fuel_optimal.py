"""The convex fuel-optimal descent (lossless convexification) against closed forms and its own constraints."""
from __future__ import annotations

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
