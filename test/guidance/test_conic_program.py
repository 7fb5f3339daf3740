"""The programme canonicalised once and solved by Clarabel directly: cvxpy's own data and answers."""
from __future__ import annotations

import math

import cvxpy as cp
import numpy as np
import pytest

from lander_autopilot.guidance.conic_program import ConicProgram


def _socp(n: int = 6) -> tuple[cp.Problem, dict[str, cp.Parameter], cp.Variable]:
    """A small DPP programme with what the MPC's has: vector, matrix and scalar parameters (signed
    ones too), equalities, inequalities, norms in the cost and in the constraints."""
    x = cp.Variable((n, 3))
    p = {"x0": cp.Parameter(3), "step": cp.Parameter(nonneg=True), "push": cp.Parameter((n - 1, 3)),
         "slow": cp.Parameter((n - 1, 3), nonpos=True), "bound": cp.Parameter(n, nonneg=True),
         "weight": cp.Parameter(n, nonneg=True), "end": cp.Parameter(nonneg=True)}
    mean = (x[:-1] + x[1:]) / 2
    cons = [x[0] == p["x0"],
            x[1:] == x[:-1] + p["step"] * x[:-1] + p["push"] + cp.multiply(p["slow"], mean),
            cp.norm(x, axis=1) <= p["bound"],
            x[:, 2] >= math.cos(0.7) * cp.norm(x, axis=1) - 1.0]
    cost = cp.sum(cp.multiply(p["weight"], cp.norm(x, axis=1))) + p["end"] * cp.norm1(x[-1] - np.array([0.0, 0.0, 1.0]))
    return cp.Problem(cp.Minimize(cost), cons), p, x


def _values(p: dict[str, cp.Parameter], rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Random values of each parameter's sign, for which the programme is feasible: small steps and
    pushes, bounds well over what they reach."""
    values = {k: 0.1 * rng.normal(size=v.shape) for k, v in p.items()}
    for k in ("step", "weight", "end"):
        values[k] = np.abs(values[k])
    values["slow"] = -np.abs(values["slow"])
    values["bound"] = 10.0 + rng.uniform(size=p["bound"].shape)
    values["x0"] = np.array([0.1, -0.2, 0.5])
    return values


def _give(program: ConicProgram, p: dict[str, cp.Parameter], values: dict[str, np.ndarray]) -> None:
    for k, v in values.items():
        p[k].value = v  # cvxpy's own, for its canonicalisation and solve
        program.set(p[k], v)


def test_the_data_is_cvxpys_own_canonical_data_at_any_parameter_values() -> None:
    problem, p, _x = _socp()
    program = ConicProgram(problem)
    rng = np.random.default_rng(7)
    for _ in range(5):
        _give(program, p, _values(p, rng))
        A, b, c = program.data()
        data, _chain, _inverse = problem.get_problem_data(cp.CLARABEL)
        # the same sparse products of the same tensor: equal, not merely close
        np.testing.assert_array_equal(A.toarray(), data["A"].toarray())
        np.testing.assert_array_equal(b, data["b"])
        np.testing.assert_array_equal(c, data["c"])


def test_the_solution_is_the_one_cvxpys_clarabel_interface_returns() -> None:
    problem, p, x = _socp()
    program = ConicProgram(problem)
    rng = np.random.default_rng(11)
    for _ in range(5):
        _give(program, p, _values(p, rng))
        assert program.solve() and program.status == "Solved"
        problem.solve(solver=cp.CLARABEL, warm_start=False)  # a fresh Clarabel solver, as here
        assert problem.status == "optimal"
        # the same data to the same solver with the same settings: the same iterates
        np.testing.assert_array_equal(program.value(x), x.value)


def test_the_values_set_are_stored_into_cvxpys_parameters_for_the_same_programme() -> None:
    problem, p, x = _socp()
    program = ConicProgram(problem)
    assert np.all(np.isnan(program.value(x)))  # nothing solved yet
    for k, v in _values(p, np.random.default_rng(3)).items():
        program.set(p[k], v)
    program.store()
    assert program.solve()
    problem.solve(solver=cp.CLARABEL, warm_start=False)
    np.testing.assert_array_equal(program.value(x), x.value)


def test_an_infeasible_programme_reports_no_solution() -> None:
    problem, p, x = _socp()
    program = ConicProgram(problem)
    values = _values(p, np.random.default_rng(5))
    values["bound"] = np.zeros(x.shape[0])  # |x_0| <= 0 against x_0 = x0 != 0
    _give(program, p, values)
    assert not program.solve()
    assert "Infeasible" in program.status and np.all(np.isnan(program.value(x)))


def test_a_programme_that_is_not_dpp_is_refused() -> None:
    # a parameter times a parameter times a variable: cvxpy would compile it anew every solve
    x, a, b = cp.Variable(2), cp.Parameter(nonneg=True), cp.Parameter(nonneg=True)
    with pytest.raises(ValueError, match="DPP"):
        ConicProgram(cp.Problem(cp.Minimize(cp.norm(x)), [a * b * x[0] >= 1.0]))
