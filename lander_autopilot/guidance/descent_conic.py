"""The linearised minimum-fuel programme of :mod:`.fuel_optimal` as conic matrices, solved by Clarabel directly.

One second-order cone programme per successive-convexification pass: the final time's step ``dt``,
the thrust bound's tangent at ``z_ref`` and the drag linearised about the last trajectory change
between passes; the shape (``N + 1`` nodes, which constraints exist) never does. So the matrices
are laid out once (a fixed sparsity pattern of index arrays) and each pass only writes their
values into one kept Clarabel solver (Goulart and Chen, "Clarabel: an interior-point solver for
conic programs with quadratic objectives", 2024; :meth:`ConicProgram.solve`) as
``min 1/2 x'Px + q'x  s.t.  Ax + s = b,  s in K``. A modelling layer (cvxpy) re-canonicalises the same programme every call, several
times the solver's own work at this size; :class:`.fuel_optimal.CvxpyProgram` keeps that
formulation as the independent cross-check.

Variables, node-major blocks over ``k = 0..N``: ``r_k`` (3), ``v_k`` (3), ``z_k = ln m_k``,
``u_k = T_k / m_k`` (3), ``sigma_k``. Constraints as :mod:`.fuel_optimal`'s module docstring and
Acikmese and Ploen (2007) eq 17-20: zero cone (initial state, end, trapezoidal dynamics with the
linearised drag ``a_D = c0 + J v``), non-negative cone (dry mass, surface, pointing limit, upper
thrust tangent, end band, drag trust region), second-order cones (``|u_k| <= sigma_k``, glide
slope, the lower thrust bound's quadratic as a rotated cone, end speed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import clarabel
import numpy as np
import scipy.sparse as sp

from .descent_problem import STRICT_CONVEXITY, DescentProblem, GuidanceError

#: [-] Clarabel's gap and feasibility tolerances: its defaults (1e-8), far under the fuel's 1e-3
#: agreement between passes and the 1e-10 log-mass tolerance of a drag-free programme's passes
SOLVER_TOLERANCE = 1e-8


@dataclass(frozen=True)
class Linearisation:
    """What a pass fixes (:mod:`.fuel_optimal`): ``mu_max`` = ``rho_max e^-z_ref`` and ``mu_max_offset``
    = ``mu_max (1 + z_ref)`` (the upper bound's tangent), ``z0`` and ``mu_min`` = ``rho_min e^-z0``
    (the lower bound's expansion, with ``rho_min > 0``), the drag ``c0`` (N+1, 3) [m/s^2] and ``J``
    (N+1, 3, 3) [1/s] about ``v_ref`` with the trust half-width ``trust`` [m/s] (with drag)."""

    mu_max: np.ndarray
    mu_max_offset: np.ndarray
    z0: np.ndarray | None = None
    mu_min: np.ndarray | None = None
    drag_c0: np.ndarray | None = None
    drag_J: np.ndarray | None = None
    v_ref: np.ndarray | None = None
    trust: float = math.inf


@dataclass(frozen=True)
class Nodes:
    """A pass's optimum at the nodes: ``r`` (N+1, 3) m, ``v`` (N+1, 3) m/s, ``z`` (N+1,) ln kg, ``u`` (N+1, 3) m/s^2."""

    r: np.ndarray
    v: np.ndarray
    z: np.ndarray
    u: np.ndarray


class _Rows:
    """Accumulates one cone's rows as COO triplets whose values are re-written every pass."""

    def __init__(self) -> None:
        self.n = 0
        self.rows: list[np.ndarray] = []
        self.cols: list[np.ndarray] = []

    def add(self, rows: np.ndarray, cols: np.ndarray) -> slice:
        """Entries at ``(self.n + rows, cols)``; returns their slice in the value array."""
        start = sum(len(r) for r in self.rows)
        self.rows.append(self.n + np.asarray(rows, int).ravel())
        self.cols.append(np.asarray(cols, int).ravel())
        return slice(start, start + self.rows[-1].size)


class ConicProgram:
    """The programme of ``problem`` with ``steps`` steps, its sparsity laid out once (module docstring)."""

    def __init__(self, problem: DescentProblem, steps: int) -> None:
        self.problem, self.N = problem, int(steps)
        N = self.N
        if N < 2:
            raise GuidanceError(f"need steps >= 2, got {steps}")
        lim, K = problem.limits, N + 1
        self.drag = problem.drag is not None
        k = np.arange(K)
        # variable indices
        self.ir, self.iv = 3 * k[:, None] + np.arange(3), 3 * K + 3 * k[:, None] + np.arange(3)
        self.iz, self.iu, self.isg = 6 * K + k, 7 * K + 3 * k[:, None] + np.arange(3), 10 * K + k
        self.n = 11 * K
        ir, iv, iz, iu, isg = self.ir, self.iv, self.iz, self.iu, self.isg
        # --- zero cone: initial state, end, dynamics -------------------------------------------
        zr = _Rows()
        zr.add(np.arange(7), np.r_[ir[0], iv[0], iz[0]])
        zr.n = 7
        self.end_z = not (problem.end_band > 0)
        end_cols = ([ir[N, 2]] if self.end_z else []) + ([] if problem.free_horizontal else list(ir[N, :2]))
        end_cols += [] if problem.end_speed > 0 else list(iv[N])
        zr.add(np.arange(len(end_cols)), np.array(end_cols, int))
        zr.n += len(end_cols)
        self.n_fixed = zr.n
        # dynamics rows (k = 0..N-1, axis i): position 3N, velocity 3N, log-mass N
        kk, ii = np.meshgrid(np.arange(N), np.arange(3), indexing="ij")  # (N, 3)
        pos_row, vel_row = 3 * kk + ii, 3 * N + 3 * kk + ii
        self.dyn0 = zr.n
        # position: r_{k+1} - r_k - dt v_k - dt^2/3 (u_k + J_k v_k) - dt^2/6 (u_{k+1} + J_{k+1} v_{k+1})
        self.s_pos_r = zr.add(np.stack([pos_row, pos_row], -1), np.stack([ir[1:], ir[:-1]], -1))
        self.s_pos_v = zr.add(pos_row, iv[:-1])
        self.s_pos_u = zr.add(np.stack([pos_row, pos_row], -1), np.stack([iu[:-1], iu[1:]], -1))
        self.s_vel_v = zr.add(np.stack([vel_row, vel_row], -1), np.stack([iv[1:], iv[:-1]], -1))
        self.s_vel_u = zr.add(np.stack([vel_row, vel_row], -1), np.stack([iu[:-1], iu[1:]], -1))
        if self.drag:  # J_k v_k terms: row (k, i), column v_{k or k+1, j}
            rows_p = np.broadcast_to(pos_row[:, :, None], (N, 3, 3))
            rows_v = np.broadcast_to(vel_row[:, :, None], (N, 3, 3))
            cols_a = np.broadcast_to(iv[:-1][:, None, :], (N, 3, 3))
            cols_b = np.broadcast_to(iv[1:][:, None, :], (N, 3, 3))
            self.s_pos_Ja, self.s_pos_Jb = zr.add(rows_p, cols_a), zr.add(rows_p, cols_b)
            self.s_vel_Ja, self.s_vel_Jb = zr.add(rows_v, cols_a), zr.add(rows_v, cols_b)
        mass_row = 6 * N + np.arange(N)
        self.s_mass = zr.add(np.stack([mass_row] * 4, -1),
                             np.stack([iz[1:], iz[:-1], isg[:-1], isg[1:]], -1))
        zr.n += 7 * N
        self.n_zero = zr.n
        # --- non-negative cone (b - A x >= 0) ---------------------------------------------------
        nn = _Rows()
        nn.add(np.arange(K), iz)  # -z_k <= -ln(dry)
        nn.add(K + np.arange(K), ir[:, 2])  # -r_kz <= 0
        nn.add(np.stack([2 * K + k] * 2, -1), np.stack([iu[:, 2], isg], -1))  # -u_kz + cos(tilt) sigma_k <= 0
        self.s_upper = nn.add(np.stack([3 * K + k] * 2, -1), np.stack([isg, iz], -1))  # sigma + mu z <= mu_off
        nn.n = 4 * K
        if not self.end_z:  # |r_Nz - target_z| <= end_band
            nn.add(np.arange(2), np.array([ir[N, 2]] * 2))
            nn.n += 2
        self.trust0 = nn.n
        if self.drag:  # |v - v_ref| <= trust
            nn.add(np.arange(6 * K), np.r_[iv.ravel(), iv.ravel()])
            nn.n += 6 * K
        self.n_nonneg = nn.n
        # --- second-order cones ------------------------------------------------------------------
        so = _Rows()
        so.add(4 * k[:, None] + np.arange(4), np.c_[isg, iu])  # (sigma_k, u_k)
        so.n = 4 * K
        cones = [4] * K
        self.glide = lim.glide_slope > 0 and not problem.free_horizontal
        if self.glide:  # (r_kz - tz, tan(gs) (r_kx - tx), tan(gs) (r_ky - ty))
            self.glide0 = so.n
            so.add(3 * k[:, None] + np.arange(3), np.c_[ir[:, 2], ir[:, 0], ir[:, 1]])
            so.n += 3 * K
            cones += [3] * K
        self.lower = lim.rho_min > 0
        if self.lower:  # rotated cone of sigma >= mu_min (1 - w + w^2 / 2), w = z - z0
            self.lower0 = so.n
            rows = 3 * k[:, None] + np.array([0, 0, 1, 2, 2])
            self.s_lower = so.add(rows, np.c_[isg, iz, iz, isg, iz])
            so.n += 3 * K
            cones += [3] * K
        if problem.end_speed > 0:  # (end_speed, v_N)
            self.speed0 = so.n
            so.add(1 + np.arange(3), iv[N])
            so.n += 4
            cones += [4]
        blocks = [(zr, 0), (nn, self.n_zero), (so, self.n_zero + self.n_nonneg)]
        self.rows = np.concatenate([np.concatenate(b.rows) + off for b, off in blocks])
        self.cols = np.concatenate([np.concatenate(b.cols) for b, _ in blocks])
        self.offsets = np.cumsum([0] + [sum(len(r) for r in b.rows) for b, _ in blocks])
        self.m = self.n_zero + self.n_nonneg + so.n
        # the CSC layout of A, once: each entry's slot (entries at the same place add up: a
        # velocity's own term and its drag term in one dynamics row)
        keys = self.cols * self.m + self.rows
        unique, self._slot = np.unique(keys, return_inverse=True)
        self._indices = (unique % self.m).astype(np.int64)
        self._indptr = np.searchsorted(unique // self.m, np.arange(self.n + 1)).astype(np.int64)
        u_cols = np.sort(self.iu.ravel())
        self._P_indices, self._P_indptr = u_cols, np.searchsorted(u_cols, np.arange(self.n + 1))
        self.cones = ([clarabel.ZeroConeT(self.n_zero), clarabel.NonnegativeConeT(self.n_nonneg)]
                      + [clarabel.SecondOrderConeT(d) for d in cones])
        self.settings = {refine: self._settings(refine) for refine in (False, True)}
        # constant values of A and b
        self._values0 = self._constant_values()
        self._order: np.ndarray | None = None
        self._solvers: dict[bool, Any] = {}

    @staticmethod
    def _settings(refine: bool) -> Any:
        """Clarabel's settings, with or without the iterative refinement of each KKT solve. Without,
        a 60-node pass takes half the time (measured on the de-orbit handover) and the solution
        keeps the static regularisation's error: over 56 de-orbit handovers the end's equalities to
        2e-11 m and the fuel to 2e-7 of itself against a refined pass, far inside the 1e-3 to which
        successive passes agree. Presolve is off: a kept solver's data is updated in place
        (:meth:`solve`), which needs the rows it was built with."""
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
            setattr(settings, name, SOLVER_TOLERANCE)
        settings.iterative_refinement_enable = refine
        settings.presolve_enable = False  # the data is updated in place between passes (fixed pattern)
        return settings

    def _constant_values(self) -> np.ndarray:
        """The entries of A that no pass changes (the rest are written in :meth:`solve`)."""
        p, lim, N, K = self.problem, self.problem.limits, self.N, self.N + 1
        zr = np.r_[np.ones(7), np.ones(self.n_fixed - 7)]
        vals = [zr]
        # dynamics: placeholders, written per pass (same order as the slices in __init__)
        n_dyn = (self.offsets[1] - zr.size)
        vals.append(np.zeros(n_dyn))
        nn = [-np.ones(K), -np.ones(K), np.c_[-np.ones(K), np.full(K, math.cos(lim.max_tilt))].ravel(),
              np.zeros(2 * K)]
        if not self.end_z:
            nn.append(np.array([1.0, -1.0]))
        if self.drag:
            nn.append(np.r_[np.ones(3 * K), -np.ones(3 * K)])
        vals.append(np.concatenate(nn))
        so = [-np.ones(4 * K)]
        if self.glide:
            t = math.tan(lim.glide_slope)
            so.append(np.tile([-1.0, -t, -t], K))
        if self.lower:
            so.append(np.zeros(5 * K))
        if p.end_speed > 0:
            so.append(-np.ones(3))
        vals.append(np.concatenate(so))
        del N
        return np.concatenate(vals)

    def matrices(self, dt: float, lin: Linearisation) -> tuple[Any, np.ndarray, Any, np.ndarray]:
        """``(P, q, A, b)`` of the pass with step ``dt`` [s] and linearisation ``lin`` (CSC matrices;
        rows of A and b: the zero cone's ``n_zero``, the non-negative cone's ``n_nonneg``, then the
        second-order cones)."""
        p, lim, N, K = self.problem, self.problem.limits, self.N, self.N + 1
        g = np.array([0.0, 0.0, -p.gravity])
        vals = self._values0.copy()
        o = self.offsets[0]
        h2, h6 = dt * dt / 3, dt * dt / 6
        vals[o + self.s_pos_r.start:o + self.s_pos_r.stop] = np.tile([1.0, -1.0], 3 * N)
        vals[o + self.s_pos_v.start:o + self.s_pos_v.stop] = -dt
        vals[o + self.s_pos_u.start:o + self.s_pos_u.stop] = np.tile([-h2, -h6], 3 * N)
        vals[o + self.s_vel_v.start:o + self.s_vel_v.stop] = np.tile([1.0, -1.0], 3 * N)
        vals[o + self.s_vel_u.start:o + self.s_vel_u.stop] = -dt / 2
        vals[o + self.s_mass.start:o + self.s_mass.stop] = np.tile([1.0, -1.0, lim.alpha * dt / 2, lim.alpha * dt / 2], N)
        b_dyn_pos = np.broadcast_to(dt * dt / 2 * g, (N, 3)).copy()
        b_dyn_vel = np.broadcast_to(dt * g, (N, 3)).copy()
        if self.drag:
            assert lin.drag_J is not None and lin.drag_c0 is not None and lin.v_ref is not None
            J, c0 = lin.drag_J, lin.drag_c0
            vals[o + self.s_pos_Ja.start:o + self.s_pos_Ja.stop] = (-h2 * J[:-1]).ravel()
            vals[o + self.s_pos_Jb.start:o + self.s_pos_Jb.stop] = (-h6 * J[1:]).ravel()
            vals[o + self.s_vel_Ja.start:o + self.s_vel_Ja.stop] = (-dt / 2 * J[:-1]).ravel()
            vals[o + self.s_vel_Jb.start:o + self.s_vel_Jb.stop] = (-dt / 2 * J[1:]).ravel()
            b_dyn_pos += h6 * (2 * c0[:-1] + c0[1:])
            b_dyn_vel += dt / 2 * (c0[:-1] + c0[1:])
        o = self.offsets[1]
        vals[o + self.s_upper.start:o + self.s_upper.stop] = np.c_[np.ones(K), lin.mu_max].ravel()
        b_end: list[float] = [p.target_L[2]] if self.end_z else []
        b_end += [] if p.free_horizontal else [p.target_L[0], p.target_L[1]]
        b_end += [] if p.end_speed > 0 else [0.0, 0.0, 0.0]
        b_zero = np.r_[p.position_L, p.velocity_L, math.log(p.mass), b_end, b_dyn_pos.ravel(), b_dyn_vel.ravel(), np.zeros(N)]
        b_nn = [np.full(K, -math.log(lim.dry_mass)), np.zeros(K), np.zeros(K), lin.mu_max_offset]
        if not self.end_z:
            b_nn.append(np.array([p.target_L[2] + p.end_band, p.end_band - p.target_L[2]]))
        if self.drag:
            v_ref = np.asarray(lin.v_ref).ravel()
            b_nn.append(np.r_[v_ref + lin.trust, lin.trust - v_ref])
        b_so = [np.zeros(4 * K)]
        if self.glide:
            t = math.tan(lim.glide_slope)
            b_so.append(np.c_[np.full(K, -p.target_L[2]), np.full(K, -t * p.target_L[0]),
                              np.full(K, -t * p.target_L[1])].ravel())
        if self.lower:
            assert lin.mu_min is not None and lin.z0 is not None
            o = self.offsets[2]
            two_mu = -2.0 / lin.mu_min
            vals[o + self.s_lower.start:o + self.s_lower.stop] = np.c_[two_mu, np.full(K, -2.0), np.full(K, -2.0),
                                                                       two_mu, np.full(K, -2.0)].ravel()
            b_so.append(np.c_[-2 * lin.z0 - 1, -2 * lin.z0, -2 * lin.z0 - 3].ravel())
        if p.end_speed > 0:
            b_so.append(np.array([p.end_speed, 0.0, 0.0, 0.0]))
        b = np.concatenate([b_zero, *b_nn, *b_so])
        data = np.bincount(self._slot, weights=vals, minlength=self._indices.size)
        A = sp.csc_matrix((data, self._indices, self._indptr), shape=(self.m, self.n))
        q = np.zeros(self.n)
        q[self.iz[N]] = -1.0  # maximise ln m_N
        # the strictly convex touch on the thrust's energy with drag (descent_problem.STRICT_CONVEXITY)
        weight = 2 * STRICT_CONVEXITY * dt if self.drag else 0.0
        P = sp.csc_matrix((np.full(self._P_indices.size, weight), self._P_indices, self._P_indptr), shape=(self.n, self.n))
        return P, q, A, b

    def solve(self, dt: float, lin: Linearisation, refine: bool = True) -> Nodes | None:
        """The optimum of the pass with step ``dt`` [s] and linearisation ``lin``, or None when Clarabel
        finds it infeasible or does not solve it (to its full or reduced tolerances). ``refine``:
        Clarabel's iterative refinement (:meth:`_settings`).

        One solver per setting is kept and its data updated in place (the sparsity never changes),
        so the set-up of the KKT factorisation is paid once for all the passes of a search (a
        quarter of a pass's time at 60 nodes). It keeps the scaling (equilibration) of the data it
        was built with: a pass's answer then depends, within the solver's tolerance, on the passes
        of this programme before it, all of them made by one deterministic search from one problem."""
        P, q, A, b = self.matrices(dt, lin)
        solver = self._solvers.get(refine)
        if solver is None:
            solver = self._solvers[refine] = clarabel.DefaultSolver(P, q, A, b, self.cones, self.settings[refine])
        else:
            solver.update(P=P.data, q=q, A=A.data, b=b)
        sol = solver.solve()
        if str(sol.status) not in ("Solved", "AlmostSolved"):
            return None
        x = np.asarray(sol.x)
        return Nodes(r=x[self.ir], v=x[self.iv], z=x[self.iz], u=x[self.iu])
