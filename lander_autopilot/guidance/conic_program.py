"""A parametrised cvxpy programme canonicalised once and handed to Clarabel directly each solve.

Plain numpy, scipy and cvxpy (no rclpy). A receding-horizon law solves the same second-order cone
programme every control period with new parameter values (the measured state, the step, the
bounds). ``Problem.solve`` runs, every call, the Python machinery around the solver: the reduction
chain's bookkeeping, the parameter checks, the sparse matrices rebuilt by scipy, the solution
mapped back to every variable and dual. For a programme of ~250 variables that costs about what
Clarabel's own iterations cost, and being many small Python steps it is the part that stretches
most when other processes share the cores.

Here the programme is canonicalised once (``Problem.get_problem_data``). It must be DPP
(disciplined parametrised, Agrawal et al., "Differentiable convex optimization layers",
NeurIPS 2019): its conic data is then an affine map of the parameters, which cvxpy hands over as a
sparse tensor. Each solve is

1. the parameter vector (every parameter's value, column-major, then 1) times three sparse
   matrices taken from that tensor once: the values of ``A`` in a fixed CSC pattern, ``b`` and
   ``c`` of Clarabel's standard form ``min c'x  s.t.  A x + s = b,  s in K`` (zero cone,
   non-negative orthant, second-order cones, in cvxpy's order and with the sign convention of
   cvxpy's own Clarabel interface). The same products ``ParamConeProg.apply_parameters`` forms,
   without its scipy re-indexing (checked entry by entry in ``test/guidance/test_conic_program.py``);
2. a fresh ``clarabel.DefaultSolver`` on that data with Clarabel's default settings;
3. the variables read from the solution vector by their columns (``var_id_to_col``).

Why a fresh solver and not ``DefaultSolver.update`` on a kept one: an update keeps the
equilibration (the rows' and columns' scaling) computed for the first data, so a period's answer
would depend on which periods came before it, within the tolerance. A fresh one makes each answer
a function of that period's parameters alone (a replayed state gives the same command); its
set-up (equilibration, the KKT system's symbolic factorisation) is about a quarter of a solve's
time at the MPC's size (profiled over its periods), and the plans of cvxpy's kept, updated solver
differ from a fresh one's by up to 3e-3 (m, m/s, m/s^2) over a de-orbit flight
(``bench/guidance_mpc.py``, "A, cvxpy kept"): within the tolerance, but an answer that depends on
the periods before it.
Why no warm start: Clarabel is an interior-point method; it starts from its own central point,
so the previous period's solution cannot shorten its iterations.
"""
from __future__ import annotations

from typing import Any

import numpy as np

#: Clarabel's statuses that carry a solution: converged to its tolerances, or to its reduced ones
#: (what cvxpy reports as ``optimal`` and ``optimal_inaccurate``)
SOLVED = ("Solved", "AlmostSolved")


class ConicProgram:
    """``problem`` (a DPP cvxpy problem of zero, non-negative and second-order cones, linear
    objective) ready to solve with its parameters' current values (:meth:`solve`); :meth:`value`
    reads a variable of the last solution."""

    def __init__(self, problem: Any) -> None:
        import clarabel
        import cvxpy as cp
        import scipy.sparse as sp

        if not problem.is_dcp(dpp=True):
            raise ValueError("the programme must be DPP: its data is then affine in the parameters")
        self.problem = problem
        data, _chain, _inverse = problem.get_problem_data(cp.CLARABEL)
        prog = data[cp.settings.PARAM_PROB]
        dims = data["dims"]
        if dims.psd or dims.exp or dims.p3d or getattr(dims, "pnd", []) or prog.P is not None:
            raise ValueError(f"only zero, non-negative and second-order cones and a linear objective, got {dims}")
        self._cones: list[Any] = []
        if dims.zero:
            self._cones.append(clarabel.ZeroConeT(dims.zero))
        if dims.nonneg:
            self._cones.append(clarabel.NonnegativeConeT(dims.nonneg))
        self._cones += [clarabel.SecondOrderConeT(d) for d in dims.soc]
        n, m = int(prog.x.size), int(prog.constr_size)
        # The tensor's rows are the entries of [A_cvx | b] column by column (m rows, n + 1 columns);
        # its columns the parameter vector. Clarabel's A is -A_cvx (cvxpy's interface does the same).
        tensor = sp.csr_matrix(prog.A)
        if tensor.shape[0] != m * (n + 1):
            raise ValueError(f"unexpected data tensor shape {tensor.shape} for {m} rows, {n} columns")
        rows = np.flatnonzero(np.diff(tensor.indptr[:m * n + 1]))  # entries of A any parameter can make
        self._A_of_p = -tensor[rows]
        self._A_indices = (rows % m).astype(np.int64)
        self._A_indptr = np.r_[0, np.cumsum(np.bincount(rows // m, minlength=n))].astype(np.int64)
        self._b_of_p = tensor[m * n:]
        self._c_of_p = sp.csr_matrix(prog.q)[:n]
        self._shape = (m, n)
        self._p = np.zeros(prog.total_param_size + 1)
        self._slots: dict[int, tuple[int, int]] = {}  # parameter id: (first column, size)
        self._by_id = dict(prog.id_to_param)
        for pid, col in prog.param_id_to_col.items():
            if pid in prog.id_to_param:
                self._slots[pid] = (col, prog.param_id_to_size[pid])
            else:  # the constant column
                self._p[col] = 1.0
        self._var_col = prog.var_id_to_col
        self._P = sp.csc_matrix((n, n))  # no quadratic term
        self._settings = clarabel.DefaultSettings()
        self._settings.verbose = False
        self._new_solver = clarabel.DefaultSolver
        self._csc = sp.csc_matrix
        self.x: np.ndarray = np.full(n, np.nan)
        self.status = "Unsolved"
        self.iterations = 0

    def set(self, parameter: Any, value: Any) -> None:
        """Give ``parameter`` (one of the problem's) ``value`` for the next solves. Unlike cvxpy's
        ``Parameter.value`` it does not check the value against the parameter's sign: the caller
        computes values that have it (a negative where ``nonneg`` was declared would make the
        programme another one, no longer convex in the same way)."""
        col, size = self._slots[parameter.id]
        self._p[col:col + size] = np.ravel(value, order="F")

    def store(self) -> None:
        """Give cvxpy's parameters the values :meth:`set` gave (to solve the very same programme
        through ``Problem.solve``, as ``bench/guidance_mpc.py`` does beside :meth:`solve`)."""
        for pid, (col, size) in self._slots.items():
            param = self._by_id[pid]
            param.value = self._p[col:col + size].reshape(param.shape, order="F")

    def data(self) -> tuple[Any, np.ndarray, np.ndarray]:
        """Clarabel's ``(A, b, c)`` at the parameters' values given by :meth:`set` (``A`` sparse CSC)."""
        p = self._p
        A = self._csc((self._A_of_p @ p, self._A_indices, self._A_indptr), shape=self._shape)
        return A, self._b_of_p @ p, self._c_of_p @ p

    def solve(self) -> bool:
        """Solve with the parameters' values given by :meth:`set`; True when a solution is there to read."""
        A, b, c = self.data()
        solution = self._new_solver(self._P, c, A, b, self._cones, self._settings).solve()
        self.status, self.iterations = str(solution.status), int(solution.iterations)
        ok = self.status in SOLVED
        self.x = np.asarray(solution.x, float) if ok else np.full(self.x.size, np.nan)
        return ok

    def value(self, variable: Any) -> np.ndarray:
        """``variable``'s value in the last solution (its shape; cvxpy's column-major layout)."""
        col = self._var_col[variable.id]
        return self.x[col:col + variable.size].reshape(variable.shape, order="F")
