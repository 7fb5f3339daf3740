"""The flown back-end of the minimum-fuel descent (conic matrices laid out once, Clarabel called
directly, a search over the final time on first passes) against the independent cvxpy formulation
and against a plain scan of the final time."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_autopilot.guidance.descent_conic import ConicProgram, Linearisation
from lander_autopilot.guidance.fuel_optimal import (
    EDGE_SHARE,
    FUEL_AGREEMENT,
    MIDDLE_SHIFT,
    CvxpyProgram,
    DescentLimits,
    DescentProblem,
    FixedTimeProgram,
    solve,
)
from lander_sim.physics.constants import LANDER_DRY_MASS, LANDER_FUEL_RATE, LANDER_MAX_THRUST, SURFACE_GRAVITY

LIMITS = DescentLimits(rho_max=4 * LANDER_MAX_THRUST, alpha=LANDER_FUEL_RATE / LANDER_MAX_THRUST,
                       dry_mass=LANDER_DRY_MASS)
#: Both back-ends stop Clarabel at a duality gap of 1e-8 (absolute) + 1e-8 |ln m_N| (~5) and primal
#: residuals of 1e-8 of the data's norm (~1e3 m, m/s): the objective ln m_N to ~1e-7, and the two
#: formulations scale their rows differently, so 1e-6 on ln m_N (the fuel to 1e-6 of the mass, a
#: few 1e-6 of the fuel, which is a fifth of the mass)
LOG_MASS = 1e-6


def _handover() -> DescentProblem:
    """The common handover case of the de-orbit tests (test/handover_case.py), as the MPC poses it."""
    from handover_case import handover_sim

    from lander_autopilot.controllers.deorbit_mpc import handover_problem

    sc, sim = handover_sim()
    s = sim.state()
    return handover_problem(sc.vehicle, s.r_W, s.v_W, s.fuel, 500.0)[0]


def _problems() -> dict[str, DescentProblem]:
    glide = DescentLimits(rho_max=LIMITS.rho_max, alpha=LIMITS.alpha, dry_mass=LIMITS.dry_mass,
                          rho_min=0.2 * LIMITS.rho_max, max_tilt=math.radians(30), glide_slope=math.radians(10))
    pinned = DescentProblem(position_L=[400.0, -150.0, 1200.0], velocity_L=[-20.0, 10.0, -45.0], mass=190.0,
                            gravity=SURFACE_GRAVITY, limits=glide, target_L=[0.0, 0.0, 500.0])
    return {
        "chute handover": _handover(),
        "pinned target, glide slope, least thrust": pinned,
        "end band and speed": dataclasses.replace(pinned, end_band=2.0, end_speed=0.2),
    }


def _first_linearisation(problem: DescentProblem, steps: int, final_time: float) -> Linearisation:
    """The first pass's linearisation (FixedTimeProgram's): the flat-out burn, a linear fall to rest."""
    lim, dt = problem.limits, final_time / steps
    t = np.arange(steps + 1) * dt
    z = np.log(np.maximum(problem.mass - lim.alpha * lim.rho_max * t, lim.dry_mass))
    mu = lim.rho_max * np.exp(-z)
    kw = {}
    if lim.rho_min > 0:
        kw.update(z0=z, mu_min=lim.rho_min * np.exp(-z))
    if problem.drag is not None:
        v = problem.velocity_L[None, :] * (1 - t / final_time)[:, None]
        r = problem.position_L[None, :] + problem.velocity_L[None, :] * (t - t * t / (2 * final_time))[:, None]
        J = problem.drag.jacobian(r, v, np.exp(z))
        kw.update(drag_c0=problem.drag.acceleration(r, v, np.exp(z)) - np.einsum("kij,kj->ki", J, v), drag_J=J,
                  v_ref=v, trust=100.0)
    return Linearisation(mu_max=mu, mu_max_offset=mu * (1 + z), **kw)


@pytest.mark.parametrize("name", list(_problems()))
def test_one_pass_is_the_cvxpy_formulations_optimum(name):
    problem = _problems()[name]
    steps, final_time = 30, 1.15 * solve(problem, steps=30, t_tol=1e-3).final_time
    lin = _first_linearisation(problem, steps, final_time)
    fast = ConicProgram(problem, steps).solve(final_time / steps, lin)
    oracle = CvxpyProgram(problem, steps).solve(final_time / steps, lin)
    assert fast is not None and oracle is not None
    assert abs(fast.z[-1] - oracle.z[-1]) < LOG_MASS
    # and the same end where it is pinned (at rest on the target, or at rest at the chute's hover
    # altitude): to the solvers' feasibility tolerance of a 1 km problem. Within an end band the
    # end is a face of equal fuel, any point of which is the optimum.
    if problem.end_band == 0 and problem.end_speed == 0:
        np.testing.assert_allclose(fast.r[-1, 2], oracle.r[-1, 2], atol=1e-4)
        np.testing.assert_allclose(fast.v[-1], oracle.v[-1], atol=1e-4)


def test_an_infeasible_pass_is_none_in_both_formulations():
    problem = _problems()["chute handover"]
    steps, final_time = 20, 3.0  # 37 m/s down at 850 m cannot stop at 500 m in 3 s
    lin = _first_linearisation(problem, steps, final_time)
    assert ConicProgram(problem, steps).solve(final_time / steps, lin) is None
    assert CvxpyProgram(problem, steps).solve(final_time / steps, lin) is None


def test_the_search_is_the_cvxpy_backends_search_under_the_chute():
    problem = _problems()["chute handover"]
    fast = solve(problem, steps=30, t_tol=1e-3)
    oracle = solve(problem, steps=30, t_tol=1e-3, backend="cvxpy")
    # the same search on the same programme: the passes' own agreement bounds the difference
    assert fast.fuel == pytest.approx(oracle.fuel, rel=FUEL_AGREEMENT)
    assert fast.final_time == pytest.approx(oracle.final_time, rel=1e-3)


def test_no_final_time_on_a_scan_beats_the_search():
    """A scan of the converged fuel over the final times about the optimum (the plain search's
    trials, 1e-3 of the final time apart) finds none cheaper than the search's answer beyond the
    passes' agreement (FUEL_AGREEMENT of the fuel burnt)."""
    problem = _problems()["chute handover"]
    sol = solve(problem, steps=30, t_tol=1e-3)
    program = FixedTimeProgram(problem, 30)
    fuels = [s.fuel for t in sol.final_time * (1 + 1e-3 * np.arange(-20, 41)) if (s := program.solve(float(t))) is not None]
    assert len(fuels) > 30
    assert sol.fuel <= min(fuels) * (1 + FUEL_AGREEMENT)
    # the search's trials are first passes, one convex solve each: far fewer than 30 a final time
    assert sol.solve_count < 60


def test_a_warm_start_from_a_coarser_programme_settles_at_its_cold_optimum():
    """A solution on 20 nodes read at a 60-node programme's fractions of the descent starts that
    programme's drag iteration: it settles (in one pass where the drag is consistent at once) on the
    optimum the cold iteration finds, to the passes' agreement."""
    problem = _problems()["chute handover"]
    tf = solve(problem, steps=60, t_tol=1e-3).final_time * 1.01
    coarse = FixedTimeProgram(problem, 20).solve(tf)
    assert coarse is not None
    fine = FixedTimeProgram(problem, 60)
    warm = fine.solve(tf, warm=coarse)
    cold_program = FixedTimeProgram(problem, 60)
    cold = cold_program.solve(tf)
    assert warm is not None and cold is not None and len(warm.t) == 61
    assert warm.fuel == pytest.approx(cold.fuel, rel=FUEL_AGREEMENT)
    np.testing.assert_allclose(warm.position_L[-1], cold.position_L[-1], atol=1e-6)
    assert fine.solves < cold_program.solves


def test_the_search_on_more_nodes_never_ends_later_than_on_its_coarse_programme():
    """More nodes place the burn's switch more finely: the search on 60 nodes ends at or before the
    one on the coarse programme alone (20), and for no more fuel than that one's final time gives."""
    problem = _problems()["chute handover"]
    fine, coarse = solve(problem, steps=60, t_tol=1e-3), solve(problem, steps=20, t_tol=1e-3)
    assert fine.final_time <= coarse.final_time * (1 + 1e-9)
    at_coarse = FixedTimeProgram(problem, 60).solve(coarse.final_time)
    assert at_coarse is not None and fine.fuel <= at_coarse.fuel * (1 + FUEL_AGREEMENT)


def test_a_search_that_ends_on_the_middle_programme_keeps_its_tolerance():
    """With the MPC's tolerance (1e-3) the golden section runs on MIDDLE_STEPS nodes and the caller's
    programme is solved once at its minimum: the final time is the 60-node search's (to 1e-5) within
    the middle programme's shift plus the section's own end, and the fuel within the passes'
    agreement."""
    problem = _problems()["chute handover"]
    fast = solve(problem, steps=60, t_tol=1e-3)
    exact = solve(problem, steps=60, t_tol=1e-5)
    assert len(fast.t) == 61
    assert abs(fast.final_time - exact.final_time) <= (MIDDLE_SHIFT + 1e-3 * EDGE_SHARE + 1e-5) * exact.final_time
    assert fast.fuel == pytest.approx(exact.fuel, rel=FUEL_AGREEMENT)
    assert fast.solve_count < exact.solve_count


def test_a_search_on_the_coarse_programme_itself_ends_there():
    """Where the caller's programme is the coarse one (the de-orbit MPC's 20 nodes), the search is
    the coarse stage of the 60-node search and nothing more: no more solves than that search, and
    the same final time as its coarse stage would give it."""
    problem = _problems()["chute handover"]
    own, fine = solve(problem, steps=20, t_tol=1e-3), solve(problem, steps=60, t_tol=1e-3)
    assert own.solve_count < fine.solve_count
    assert len(own.t) == 21 and fine.final_time <= own.final_time * (1 + 1e-9)
