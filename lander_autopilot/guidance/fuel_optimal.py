"""Minimum-fuel powered descent of a point mass by lossless convexification.

The yardstick the flown descent laws are measured against: from a handover state (position and
velocity in the local frame, mass) to rest at a target point, the least fuel any thrust history
within the vehicle's limits can use. Method: Acikmese and Ploen, "Convex Programming Approach to
Powered Descent Guidance for Mars Landing", J. Guidance, Control, and Dynamics 30(5), 2007
(problems 3-4 there; equation numbers below are theirs).

Model (local frame, z up, uniform gravity ``g_L = (0, 0, -g)``; the powered phase lasts a minute at
most and spans a few km, where inverse-square gravity differs from uniform by < 0.3 %)::

    r' = v,   v' = T / m + g_L,   m' = -alpha |T|,   rho_min <= |T| <= rho_max,
    n . T >= |T| cos(theta_max)   (pointing limit, n = up)

Change of variables (their eq 17-18): ``sigma = Gamma / m``, ``u = T / m``, ``z = ln m``, so that
``z' = -alpha sigma`` and the non-convex ``rho_min <= |T|`` becomes ``|u| <= sigma`` with ``sigma``
bounded by the second-order expansions of ``rho e^-z`` about ``z0(t) = ln(m0 - alpha rho_max t)``
(their eq 19-20; lossless: at the optimum ``|u| = sigma``, their theorem 2).
Discretised with the control held over each of ``N`` steps (exact for piecewise-constant ``u`` and
``sigma``). Minimising fuel is maximising ``z(t_f)``. The final time is free: a search on
``t_f`` (the optimum fuel is unimodal in ``t_f``, their section IV.C; "The final time" below).

Drag (optional, ``DescentProblem.drag``): the open parachute of a Mars descent pulls about the
weight at its terminal speed, so a yardstick without it would be no yardstick. The drag acceleration
``a_D = -k rho(h) |v| v / m`` (``k = sum 1/2 Cd A``, exponential density) is not convex in ``v``; it
is linearised about the last solution's ``(h, v, m)`` at every node,
``a_D ~ a_D(v_ref) + J (v - v_ref)`` with ``J = -(k rho / m)(|v| I + v v^T / |v|)``, and the
programme re-solved until the fuel and the trajectory stop changing (successive convexification,
Mao, Szmuk and Acikmese, "Successive convexification of non-convex optimal control problems",
CDC 2016; relaxed fixed-point steps once the plain iteration stops contracting).
At convergence the drag is exact at the nodes; the result is a local optimum of the problem with
drag, which for this one-burn descent is the optimum (a coast under the chute then one burn).

The final time. Under the open chute the fuel is least just past the *shortest* feasible final
time: drag brakes for free only while the lander falls fast, so the optimum coasts at terminal
speed as long as it can and stops with a late full-thrust burn; shorter final times are
infeasible (no burn stops the fall in time), and the fuel falls steeply from the edge into its
minimum (~10 kg/s over the first hundredths of a second on a de-orbit case) and rises slowly past
it (~0.8 kg/s on the common handover, whose minimum is on the edge itself). A drag-free vertical
fall to rest is the same bang-bang, on the edge. So the search is (1) a scan, short final times
first, for the first feasible one on a grid; (2) bisection of the feasibility edge below it, each
trial one convex solve, the first pass (thrust bound about the flat-out burn, drag about a linear
fall to rest: feasibility needs no converged drag); (3) from the edge, steps doubling until the
fuel rises, then golden section inside that bracket (unimodal), the drag converged at each trial
but started from the converged trial nearest in final time (one pass where a cold start takes
three to fifteen: a warm start counts as the pass before it, so a trial whose drag is consistent
with its own trajectory and whose fuel agrees with its neighbour's is settled at once; the first
pass's own fuel is biased by its crude linearisation, enough to move the minimum beside the steep
edge). All on a coarse programme of ``SEARCH_STEPS`` nodes (a pass there costs a third of one on
60), then (4) the golden section again on the caller's ``steps``, from ``FINE_BRACKET`` below the
coarse minimum up to it: more nodes place the burn's switch more finely, so the edge and the
minimum come earlier, never later (measured on 56 de-orbit handovers: 0 to 9.3e-4 of the final
time earlier; 9.4e-4 on a drag-free fall of 26 s). Where the caller's tolerance allows
(``MIDDLE_SHIFT``), that golden section runs on ``MIDDLE_STEPS`` nodes instead, and (5) the
caller's programme is solved once at its minimum, its drag started from there: the MPC's reference
(60 nodes, 1e-3) then takes ~35 convex solves, 26 on 20 nodes, 8 on 30 and one on 60; (6) where the
drag settles at none of the trials, a plain search on the caller's programme is the fall-back.

Every pass is solved without the solver's iterative refinement (:meth:`.descent_conic.ConicProgram._settings`,
half the time of a pass): the solutions handed out carry the static regularisation's error, measured
over those handovers as the end's equalities to 2e-11 m and the fuel to 2e-7 of itself against a
refined pass, far inside the 1e-3 to which the passes agree. One solver object serves all the
passes of a programme, its data updated in place (the sparsity is fixed): the set-up of the KKT
system's factorisation is paid once per search, not once per pass.

Solver: Clarabel (an interior-point conic solver, installed with the project) on the conic
matrices laid out once (:mod:`.descent_conic`): the problem is a second-order cone programme,
which OSQP (a QP solver) cannot take. Measured side by side on the de-orbit handovers
(bench/guidance_reference.py): the modelling layer's canonicalisation and Clarabel's iterative
refinement were each about half of a 60-node pass; QOCO and ECOS (smaller interior-point codes)
solved the same matrices no faster than Clarabel on this 2-core machine (a few runs each, the
machine shared). What is left is Clarabel's own iterations (~15 a pass, ~0.12 ms each on 20 nodes,
~0.33 ms on 60). A solver generated for the fixed shape (QOCOGEN 0.1.9, measured on 95 of these
passes of each size against the kept Clarabel solver) is 1.2-1.4 x faster where it solves, but ends
12-29 % of the feasible passes in a numerical error, detects no infeasibility (which the edge's
bisection needs), and takes minutes to generate and compile per shape: not worth a fall-back solver
and a C build in the set-up.
:class:`CvxpyProgram` keeps the cvxpy formulation as an independent cross-check (``backend``).
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from .descent_conic import ConicProgram, Linearisation, Nodes
from .descent_problem import (
    MIN_AIRSPEED,
    STRICT_CONVEXITY,
    DescentLimits,
    DescentProblem,
    DescentSolution,
    DragModel,
    GuidanceError,
    drag_up,
)

#: the problem's names are re-exported: callers import them from here
__all__ = ["MIN_AIRSPEED", "STRICT_CONVEXITY", "CvxpyProgram", "DescentLimits", "DescentProblem", "DescentSolution",
           "DragModel", "FixedTimeProgram", "GuidanceError", "drag_up", "solve", "solve_fixed_time", "vertical_bang_bang"]

#: [-] the first pass's trust region on the velocity, in units of ``1 + |v0|`` m/s: wide (the
#: relaxation damps the passes), never binding on a plan that stops the fall
TRUST_WIDTH = 10.0
#: [-] log-mass change between passes under which a drag-free programme is converged (a kilogram
#: in ten thousand tonnes: only the solver's own rounding is left)
LOG_MASS_TOLERANCE = 1e-10
#: [m/s^2] the drag the programme flew (linearised) against its trajectory's true drag: 0.3 % of g,
#: ~0.2 m/s over a 20-s burn, ~0.3 % of its fuel
DRAG_RESIDUAL = 1e-2
#: [-] fuel agreement between passes, of the fuel burnt: the passes scatter by ~1e-4 (the optimum
#: is flat along a coast node's timing), and a yardstick for a 3 % criterion needs 0.1 %
FUEL_AGREEMENT = 1e-3
#: [-] a pass whose step is over this fraction of the last one's is not contracting: the
#: relaxation is halved (Krasnoselskii-Mann averaging), down to MIN_RELAXATION
CONTRACTION = 0.7
MIN_RELAXATION = 0.05
#: [s] the golden-section search's tolerance on the final time (the fuel is flat near its optimum)
FINAL_TIME_TOLERANCE = 1e-5
#: [s] shortest final time searched: the bracket's floor for a lander already at rest
MIN_FINAL_TIME = 1e-2
#: nodes of the coarse programme the final-time search runs on before the caller's ``steps``: the
#: feasibility edge at 20 nodes lies within 3 ms of the edge at 60 on the common handover case
#: (12.7203 s against 12.7182 s), a quarter of the 1e-3 relative tolerance asked of the reference
SEARCH_STEPS = 20
#: [-] how far below the coarse minimum the caller's programme searches, of the final time: its
#: minimum comes 0 to 9.4e-4 earlier (module docstring, (4)), with half as much again in hand
FINE_BRACKET = 1.5e-3
#: nodes of the programme the final-time search ends on, then one pass on the caller's ``steps``
#: at its minimum, where the caller's tolerance allows (MIDDLE_SHIFT): a pass there costs half of one
#: on 60 nodes
MIDDLE_STEPS = 30
#: [-] how far the 60-node minimum lies from the 30-node one, of the final time: measured 2.2e-4 at
#: most over 56 de-orbit handovers (the 60-node fuel at the 30-node minimum within 7e-5 of its own
#: optimum's); the search ends on the middle programme only where ``t_tol * EDGE_SHARE`` is no finer
MIDDLE_SHIFT = 2.5e-4
#: [-] the golden sections end at this share of the final time's tolerance: beside the feasibility
#: edge the fuel is steep (falling by ~10 kg/s into its minimum, rising by ~0.8 kg/s past it
#: under the chute), so an error in ``t_f`` there costs fuel to first order, not second
EDGE_SHARE = 0.25
#: [-] margin on the bracket's upper end, the burn the fuel allows at the larger of the least thrust
#: and half the weight (their eq 46): the golden-section search needs a bracket that holds the optimum
BRACKET_MARGIN = 1.5


class CvxpyProgram:
    """The linearised pass of :class:`FixedTimeProgram` written in cvxpy (parameters, DPP) and solved
    by Clarabel through it: the same programme as :class:`.descent_conic.ConicProgram` from an
    independent formulation, the cross-check the tests hold the flown back-end to."""

    def __init__(self, problem: DescentProblem, steps: int) -> None:
        import cvxpy as cp

        lim = problem.limits
        self.problem, self.N = problem, int(steps)
        N = self.N
        if N < 2:
            raise GuidanceError(f"need steps >= 2, got {steps}")
        g = np.array([0.0, 0.0, -problem.gravity])
        self.dt = cp.Parameter(nonneg=True)
        self.half_dt2 = cp.Parameter(nonneg=True)
        self.alpha_dt = cp.Parameter(nonneg=True)
        self.mu_max = cp.Parameter(N + 1, nonneg=True)  # rho_max e^-z_ref
        self.mu_max_offset = cp.Parameter(N + 1)  # rho_max e^-z_ref (1 + z_ref)
        self.sixth_dt2 = cp.Parameter(nonneg=True)
        self.r = r = cp.Variable((N + 1, 3))
        self.v = v = cp.Variable((N + 1, 3))
        self.z = z = cp.Variable(N + 1)
        self.u = u = cp.Variable((N + 1, 3))
        s = cp.Variable(N + 1)
        ones = np.ones((N, 1))
        acc = u  # the acceleration other than gravity at the nodes: thrust, and drag when modelled
        cons: list[Any] = []
        if problem.drag is not None:
            # a_D = c0 + J v, linearised about the last solution (module docstring)
            self.drag_c0 = cp.Parameter((N + 1, 3))
            self.drag_J = [[cp.Parameter(N + 1) for _ in range(3)] for _ in range(3)]
            self.v_ref = cp.Parameter((N + 1, 3))
            self.trust = cp.Parameter(nonneg=True)
            a_d = cp.hstack([cp.reshape(self.drag_c0[:, i] + sum(cp.multiply(self.drag_J[i][j], v[:, j])
                                                                 for j in range(3)), (N + 1, 1), order="C")
                             for i in range(3)])
            acc = u + a_d
            cons.append(cp.abs(v - self.v_ref) <= self.trust)
        cons += [
            r[0] == problem.position_L, v[0] == problem.velocity_L, z[0] == math.log(problem.mass),
            *self._end(problem, r[N], v[N]),
            r[1:] == r[:-1] + self.dt * v[:-1] + self.sixth_dt2 * (2 * acc[:-1] + acc[1:])
            + self.half_dt2 * (ones @ g[None, :]),
            v[1:] == v[:-1] + self.dt / 2 * (acc[:-1] + acc[1:]) + self.dt * (ones @ g[None, :]),
            z[1:] == z[:-1] - self.alpha_dt / 2 * (s[:-1] + s[1:]),
            z >= math.log(lim.dry_mass),
            r[:, 2] >= 0,  # never below the surface (the local frame's origin is on it)
            cp.norm(u, axis=1) <= s,
            # pointing limit: the thrust within max_tilt of the local vertical
            u[:, 2] >= math.cos(lim.max_tilt) * s,
            # upper thrust bound, tangent of rho_max e^-z at z_ref (their eq 20, right side)
            s <= self.mu_max_offset - cp.multiply(self.mu_max, z),
        ]
        if lim.rho_min > 0:
            # lower bound, second-order expansion about the flat-out burn (their eq 20, left side);
            # conservative for z > z0, which holds everywhere since z0 burns flat out
            self.mu_min = cp.Parameter(N + 1, nonneg=True)
            self.z0 = cp.Parameter(N + 1)
            cons.append(s >= cp.multiply(self.mu_min, 1 - (z - self.z0))
                        + cp.multiply(self.mu_min, cp.square(z - self.z0)) / 2)
        if lim.glide_slope > 0 and not problem.free_horizontal:
            rel = r - np.ones((N + 1, 1)) @ problem.target_L[None, :]
            cons.append(cp.norm(rel[:, :2], axis=1) * math.tan(lim.glide_slope) <= rel[:, 2])
        objective = z[N]
        if problem.drag is not None:
            objective = objective - STRICT_CONVEXITY * self.dt * cp.sum_squares(u)
        self.program = cp.Problem(cp.Maximize(objective), cons)

    @staticmethod
    def _end(problem: DescentProblem, r_end: Any, v_end: Any) -> list[Any]:
        """The end's constraints: at the target (its altitude only with ``free_horizontal``) at rest,
        or within ``end_band`` of its altitude under ``end_speed``."""
        import cvxpy as cp

        z = r_end[2] == problem.target_L[2] if problem.end_band == 0 else cp.abs(r_end[2] - problem.target_L[2]) <= problem.end_band
        cons = [z] if problem.free_horizontal else [z, r_end[:2] == problem.target_L[:2]]
        return cons + [v_end == 0 if problem.end_speed == 0 else cp.norm(v_end) <= problem.end_speed]

    def solve(self, dt: float, lin: Linearisation, refine: bool = True) -> Nodes | None:
        """The pass's optimum (:meth:`.descent_conic.ConicProgram.solve`'s contract; ``refine`` is
        cvxpy's to choose)."""
        import cvxpy as cp

        lim = self.problem.limits
        self.dt.value, self.half_dt2.value, self.alpha_dt.value = dt, dt * dt / 2, lim.alpha * dt
        self.sixth_dt2.value = dt * dt / 6
        self.mu_max.value, self.mu_max_offset.value = lin.mu_max, lin.mu_max_offset
        if lim.rho_min > 0:
            self.z0.value, self.mu_min.value = lin.z0, lin.mu_min
        if self.problem.drag is not None:
            assert lin.drag_J is not None
            self.drag_c0.value = lin.drag_c0
            for i in range(3):
                for j in range(3):
                    self.drag_J[i][j].value = lin.drag_J[:, i, j]
            self.v_ref.value, self.trust.value = lin.v_ref, lin.trust
        try:
            with warnings.catch_warnings():
                # "Solution may be inaccurate": accepted below as optimal_inaccurate, which for
                # Clarabel means its reduced tolerances (1e-4 relative) were met.
                warnings.simplefilter("ignore", UserWarning)
                self.program.solve(solver=cp.CLARABEL)
        except cp.error.SolverError:
            return None
        if self.program.status not in ("optimal", "optimal_inaccurate") or self.z.value is None:
            return None
        return Nodes(r=np.array(self.r.value), v=np.array(self.v.value), z=np.array(self.z.value),
                     u=np.array(self.u.value))


class FixedTimeProgram:
    """The minimum-fuel descent at a given final time: successive convexification of the thrust
    bound and the drag (module docstring) over passes of one convex programme, built once.

    The upper bound ``rho_max e^-z`` is convex in ``z``, so its tangent at ``z_ref`` lies below it:
    every solution is feasible for the true bound, and re-solving with ``z_ref`` at the last
    solution's log-mass makes it tight where it matters. Acikmese and Ploen expand about the
    flat-out burn ``z0(t)`` once (their eq 19-20); that is conservative by ``(z - z0)^2 / 2`` after
    a coast, a few per cent of thrust. ``backend``: ``"conic"`` (:class:`.descent_conic.ConicProgram`,
    flown) or ``"cvxpy"`` (:class:`CvxpyProgram`, the cross-check). ``solves`` counts the convex
    solves (passes) made so far. ``refine``: the solver's iterative refinement on the passes after
    the first (:meth:`_pass`).
    """

    def __init__(self, problem: DescentProblem, steps: int, backend: str = "conic", refine: bool = True) -> None:
        if backend not in ("conic", "cvxpy"):
            raise GuidanceError(f"backend must be 'conic' or 'cvxpy', got {backend!r}")
        self.problem, self.N, self.refine = problem, int(steps), refine
        self.program: ConicProgram | CvxpyProgram = (ConicProgram if backend == "conic" else CvxpyProgram)(problem, steps)
        self.solves = 0
        self._firsts: dict[float, tuple[Nodes | None, np.ndarray | None]] = {}

    def _pass(self, dt: float, z_ref: np.ndarray, z_flat: np.ndarray,
              drag_ref: tuple[np.ndarray, np.ndarray, float] | None,
              refine: bool = True) -> tuple[Nodes | None, np.ndarray | None]:
        """One convex solve about ``z_ref`` (and the drag about ``(r_ref, v_ref, trust)``); returns the
        pass's nodes and the drag's Jacobian ``J`` it was linearised with (None without drag).
        ``refine`` as :meth:`.descent_conic.ConicProgram.solve`'s: off for a first pass, which
        decides feasibility and the next linearisation only (a solution handed out always comes
        from a later pass)."""
        lim, drag = self.problem.limits, self.problem.drag
        mu = lim.rho_max * np.exp(-z_ref)
        kw: dict[str, Any] = {}
        J = None
        if lim.rho_min > 0:
            kw.update(z0=z_flat, mu_min=lim.rho_min * np.exp(-z_flat))
        if drag is not None and drag_ref is not None:
            r_ref, v_ref, trust = drag_ref
            m_ref = np.exp(z_ref)
            J = drag.jacobian(r_ref, v_ref, m_ref)
            c0 = drag.acceleration(r_ref, v_ref, m_ref) - np.einsum("kij,kj->ki", J, v_ref)
            kw.update(drag_c0=c0, drag_J=J, v_ref=v_ref, trust=trust)
        self.solves += 1
        return self.program.solve(dt, Linearisation(mu_max=mu, mu_max_offset=mu * (1 + z_ref), **kw), refine), J

    def first(self, final_time: float) -> Nodes | None:
        """The first pass at ``final_time`` s (the flat-out burn's thrust bound, the drag about the
        velocity falling linearly to rest), None when infeasible: one convex solve, kept for
        :meth:`solve` at the same final time."""
        if not (final_time > 0):
            raise GuidanceError(f"final_time must be positive, got {final_time}")
        if final_time not in self._firsts:
            self._firsts[final_time] = self._pass(*self._start(final_time), refine=False)
        return self._firsts[final_time][0]

    def feasible(self, final_time: float) -> bool:
        """Whether the first pass at ``final_time`` s has a solution (:meth:`first`)."""
        return self.first(final_time) is not None

    def _start(self, final_time: float) -> tuple[float, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, float] | None]:
        lim, N, m0 = self.problem.limits, self.N, self.problem.mass
        dt = final_time / N
        t = np.arange(N + 1) * dt
        # First expansion point: the flat-out burn, clipped at the dry mass past burn-out.
        z_flat = np.log(np.maximum(m0 - lim.alpha * lim.rho_max * t, lim.dry_mass))
        if self.problem.drag is None:
            return dt, z_flat, z_flat, None
        # First drag reference: the velocity falling linearly to rest, the height following it.
        p0, v0 = self.problem.position_L, self.problem.velocity_L
        v_ref = v0[None, :] * (1 - t / final_time)[:, None]
        r_ref = p0[None, :] + v0[None, :] * (t - t * t / (2 * final_time))[:, None]
        trust = TRUST_WIDTH * (1.0 + float(np.linalg.norm(v0)))  # [m/s]: wide; the relaxation below damps
        return dt, z_flat, z_flat, (r_ref, v_ref, trust)

    def solve(self, final_time: float, passes: int | None = None,
              warm: DescentSolution | None = None) -> DescentSolution | None:
        """The optimum for ``final_time`` s, or None when infeasible. ``passes`` bounds the
        re-linearisations (default 4 without drag: the thrust bound's expansion converges in 2-3;
        30 with drag, whose iteration settles in 3-15 passes where it settles at all (measured on the
        de-orbit handovers; a final time that has not settled by then counts as infeasible)).
        ``warm``: a solution at a neighbouring final time (of this programme, or of another number
        of nodes, read at this programme's fractions of the descent), the first linearisation
        instead of the flat-out burn and the linear fall, and the pass before the first: near the
        optimum it is all but converged here, and one pass settles it when its drag is consistent
        with its own trajectory and its fuel agrees with ``warm``'s."""
        if not (final_time > 0):
            raise GuidanceError(f"final_time must be positive, got {final_time}")
        m0, drag = self.problem.mass, self.problem.drag
        passes = passes if passes is not None else (4 if drag is None else 30)
        dt, z_ref, z_flat, drag_ref = self._start(final_time)
        if warm is not None:
            pos, vel, mass = _at_fractions(warm, self.N)
            z_ref = np.log(mass)
            if drag_ref is not None:
                drag_ref = (pos, vel, drag_ref[2])
        relax, prev_step = 1.0, None
        best: float | None = None if warm is None or drag is None else math.log(float(warm.mass[-1]))
        converged = drag is None
        nodes: Nodes | None = None
        for i in range(passes):
            if i == 0 and warm is None:
                self.first(final_time)
                nodes, J = self._firsts[final_time]
            else:
                nodes, J = self._pass(dt, z_ref, z_flat, drag_ref, self.refine)
            if nodes is None:
                return None
            zN = float(nodes.z[-1])
            if drag is None or drag_ref is None or J is None:
                if best is not None and abs(zN - best) < LOG_MASS_TOLERANCE:
                    break
                best, z_ref = zN, nodes.z
                continue
            r_ref, v_ref, trust = drag_ref
            step = float(np.max(np.abs(nodes.v - v_ref)))
            # Converged when the drag the programme flew (linearised) is the true drag of its own
            # trajectory to DRAG_RESIDUAL and the fuel between passes agrees to FUEL_AGREEMENT of
            # the fuel burnt: the passes scatter by ~1e-4 (the optimum is flat along some
            # directions, a coast node's timing, and the solver returns any point of that face).
            c0 = drag.acceleration(r_ref, v_ref, np.exp(z_ref)) - np.einsum("kij,kj->ki", J, v_ref)
            lin = c0 + np.einsum("kij,kj->ki", J, nodes.v)
            residual = float(np.max(np.abs(drag.acceleration(nodes.r, nodes.v, np.exp(nodes.z)) - lin)))
            if residual < DRAG_RESIDUAL and best is not None and abs(math.exp(zN) - math.exp(best)) < FUEL_AGREEMENT * (m0 - math.exp(zN)):
                converged = True
                break
            # Fixed-point iteration on the drag's reference, relaxed (Krasnoselskii-Mann averaging)
            # once it stops contracting: undamped, it settles into a 2-cycle when the burn's start
            # moves by a node between passes.
            if prev_step is not None and step > CONTRACTION * prev_step:
                relax = max(0.5 * relax, MIN_RELAXATION)
            prev_step = step
            drag_ref = (r_ref + relax * (nodes.r - r_ref), v_ref + relax * (nodes.v - v_ref), trust)
            z_ref = z_ref + relax * (nodes.z - z_ref)
            best = zN
        if not converged or nodes is None:
            return None  # the linearised drag never settled: no trustworthy optimum at this final time
        mass = np.exp(nodes.z)
        t = np.arange(self.N + 1) * dt
        return DescentSolution(t=t, position_L=nodes.r, velocity_L=nodes.v, mass=mass, thrust_L=nodes.u * mass[:, None],
                               fuel=float(m0 - mass[-1]), final_time=float(final_time), solve_count=1)


def _at_fractions(sol: DescentSolution, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position [m], velocity [m/s] and mass [kg] of ``sol`` at ``steps + 1`` nodes at the same
    fractions of its descent as a programme of ``steps`` steps has them (linear between ``sol``'s
    nodes; ``sol``'s own nodes when it has that many)."""
    if len(sol.t) == steps + 1:
        return sol.position_L, sol.velocity_L, sol.mass
    s, f = np.linspace(0.0, 1.0, steps + 1), sol.t / sol.final_time

    def at(a: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(s, f, a[:, i]) for i in range(a.shape[1])], axis=1)

    return at(sol.position_L), at(sol.velocity_L), np.interp(s, f, sol.mass)


def solve_fixed_time(problem: DescentProblem, final_time: float, steps: int = 60,
                     backend: str = "conic") -> DescentSolution | None:
    """The minimum-fuel descent lasting exactly ``final_time`` s, or None when none is feasible."""
    return FixedTimeProgram(problem, steps, backend).solve(final_time)


def _bracket(problem: DescentProblem) -> tuple[float, float]:
    """``[t_lo, t_hi]``: half the time to cancel the speed at full thrust, and the longest burn the
    fuel allows at the larger of the least thrust and half the weight (their eq 45-46), with margin."""
    lim, m0 = problem.limits, problem.mass
    speed = float(np.linalg.norm(problem.velocity_L))
    t_lo = max(MIN_FINAL_TIME, speed * m0 / lim.rho_max) * 0.5
    t_hi = (m0 - lim.dry_mass) / (lim.alpha * max(lim.rho_min, m0 * problem.gravity * 0.5)) * BRACKET_MARGIN
    return t_lo, max(t_hi, 2 * t_lo)


class _Search:
    """Fuel at final times on one programme, cached: ``fuel`` with the drag converged, ``first``
    from the first pass alone (one convex solve); +inf where infeasible or unsettled."""

    def __init__(self, program: FixedTimeProgram) -> None:
        self.program = program
        self.cache: dict[float, DescentSolution | None] = {}

    def fuel(self, tf: float, warm: bool = False) -> float:
        """The converged fuel at ``tf``; ``warm``: from the converged solution nearest in final time."""
        if tf not in self.cache:
            near = [s for s in self.cache.values() if s is not None]
            start = min(near, key=lambda s: abs(s.final_time - tf)) if warm and near else None
            self.cache[tf] = self.program.solve(tf, warm=start)
        sol = self.cache[tf]
        return math.inf if sol is None else sol.fuel

    def first(self, tf: float) -> float:
        nodes = self.program.first(tf)
        return math.inf if nodes is None else self.program.problem.mass - math.exp(float(nodes.z[-1]))

    def best(self) -> DescentSolution | None:
        solved = [s for s in self.cache.values() if s is not None]
        return min(solved, key=lambda s: s.fuel) if solved else None

    @staticmethod
    def golden(f: Callable[[float], float], a: float, b: float, tol: float) -> float:
        """Golden-section search of the (unimodal) ``f`` on ``[a, b]`` down to a bracket of ``tol``;
        returns the best point tried."""
        invphi = (math.sqrt(5) - 1) / 2
        c, d = b - invphi * (b - a), a + invphi * (b - a)
        tried = {c: f(c), d: f(d)}
        while b - a > tol:
            if tried[c] <= tried[d]:
                b, d = d, c
                c = b - invphi * (b - a)
                tried[c] = f(c)
            else:
                a, c = c, d
                d = a + invphi * (b - a)
                tried[d] = f(d)
        return min(tried, key=lambda t: tried[t])

    def edge(self, a: float, b: float, tol: float) -> float:
        """The shortest feasible final time in ``[a, b]`` (``a`` infeasible, ``b`` feasible), by
        bisection on the first pass's feasibility to ``tol`` s; returns the feasible end."""
        while b - a > tol:
            c = 0.5 * (a + b)
            a, b = (a, c) if self.program.feasible(c) else (c, b)
        return b

    def rise(self, t0: float, step: float, t_max: float) -> tuple[float, float]:
        """From ``t0`` (feasible) steps doubling from ``step`` until the converged fuel (each trial
        warm from the one before) rises: the bracket ``[a, b]`` of its minimum (unimodal), ``b`` at
        most ``t_max``."""
        ts, fs = [t0], [self.fuel(t0)]
        while ts[-1] < t_max:
            ts.append(min(t0 + step * 2 ** (len(ts) - 1), t_max))
            fs.append(self.fuel(ts[-1], warm=True))
            if fs[-1] > fs[-2]:
                break
        return ts[max(len(ts) - 3, 0)], ts[-1]


def solve(problem: DescentProblem, steps: int = 60, t_bounds: tuple[float, float] | None = None,
          t_tol: float = FINAL_TIME_TOLERANCE, backend: str = "conic") -> DescentSolution:
    """The minimum-fuel descent with free final time (module docstring, "The final time").

    ``t_bounds`` defaults to :func:`_bracket`'s (their eq 45-46). ``t_tol`` is relative to the
    final time (absolute under 1 s). ``backend`` as :class:`FixedTimeProgram`'s. ``solve_count`` of
    the result: the convex solves of the whole search. Raises :class:`GuidanceError` when no final
    time in the bracket is feasible.
    """
    lo, hi = map(float, t_bounds if t_bounds is not None else _bracket(problem))
    fine_program = FixedTimeProgram(problem, steps, backend, refine=False)
    middle_program = (fine_program if steps <= MIDDLE_STEPS or MIDDLE_SHIFT > t_tol * EDGE_SHARE
                      else FixedTimeProgram(problem, MIDDLE_STEPS, backend, refine=False))
    coarse_program = (middle_program if middle_program.N <= SEARCH_STEPS
                      else FixedTimeProgram(problem, SEARCH_STEPS, backend, refine=False))
    # one search (one cache) a programme: where the caller's is the middle or coarse one, so is its search
    searches = {id(p): _Search(p) for p in (fine_program, middle_program, coarse_program)}
    coarse, middle, fine = (searches[id(p)] for p in (coarse_program, middle_program, fine_program))

    def tol(t: float) -> float:
        return t_tol * max(1.0, t)

    # (1) The coarse scan, short final times first, for the first feasible one: a geometric grid
    # with drag (its feasible final times are a band near the short end), linear without.
    grid = [float(t) for t in (np.geomspace(lo, hi, 13) if problem.drag is not None else np.linspace(lo, hi, 9))]
    k = next((i for i, t in enumerate(grid) if coarse_program.feasible(t)), None)
    if k is None:
        raise GuidanceError(f"no feasible descent with final time in [{lo:.2f}, {hi:.2f}] s "
                            f"(too little fuel or thrust for this handover state)")
    # (2) the feasibility edge below it, (3) the first-pass fuel's minimum from the edge on: a
    # bracket by doubling steps, then golden section, all on the coarse programme
    t_edge = coarse.edge(grid[k - 1], grid[k], tol(grid[k])) if k > 0 else grid[0]
    a, b = coarse.rise(t_edge, tol(t_edge), hi)
    t_coarse = _Search.golden(lambda t: coarse.fuel(t, warm=True), a, b, tol(a) * EDGE_SHARE)
    # (4) golden section of the converged fuel on the middle programme (the caller's, unless its
    # tolerance allows MIDDLE_STEPS) from FINE_BRACKET below the coarse minimum up to it, the first
    # trial's drag started from the coarse optimum (at its fractions of the descent), each later one
    # from the nearest trial; (5) then the caller's programme once at the middle one's minimum
    if middle_program is not coarse_program:
        width = FINE_BRACKET * max(1.0, t_coarse)
        middle.cache[t_coarse] = middle_program.solve(t_coarse, warm=coarse.cache.get(t_coarse))
        _Search.golden(lambda t: middle.fuel(t, warm=True), max(lo, t_coarse - width), t_coarse,
                       tol(t_coarse) * EDGE_SHARE)
    if fine is not middle:
        best = middle.best()
        if best is not None:
            fine.cache[best.final_time] = fine_program.solve(best.final_time, warm=best)
    sol = fine.best()
    if sol is None:
        # (6) no settled optimum there: golden section of the converged fuel on the grid's
        # bracket of its first rise (the slow, plain search)
        fuels = [fine.fuel(t) for t in grid]
        j = int(np.argmin(fuels))
        if not math.isfinite(fuels[j]):
            raise GuidanceError(f"no final time in [{lo:.2f}, {hi:.2f}] s settles the drag's iteration")
        _Search.golden(fine.fuel, grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)], tol(grid[j]))
        sol = fine.best()
    assert sol is not None
    count = sum(p.solves for p in {id(p): p for p in (coarse_program, middle_program, fine_program)}.values())
    return DescentSolution(**{**sol.__dict__, "solve_count": count})


def vertical_bang_bang(height: float, velocity: float, mass: float, gravity: float,
                       limits: DescentLimits) -> tuple[float, float]:
    """Closed-form minimum fuel of a 1-D vertical descent to rest at height 0 (``rho_min = 0``).

    The optimum is a free fall followed by one burn at full thrust that ends at rest on the target
    (bang-bang: Pontryagin with a linear Hamiltonian in ``|T|``). The burn from speed ``v_b``
    (negative: down) with ``m(t) = m_b - q t``, ``q = alpha rho_max``, ``c = 1 / alpha`` gives
    ``v(t) = v_b + c ln(m_b / m(t)) - g t`` and a height drop
    ``v_b t - g t^2 / 2 + (c / q) ((m_b - m) - m ln(m_b / m))``. Solves the coast time with a
    bracketing root finder. Returns ``(fuel [kg], final time [s])``.
    """
    from scipy.optimize import brentq

    c = 1.0 / limits.alpha
    q = limits.alpha * limits.rho_max

    def burn(v_b: float) -> tuple[float, float]:
        # burn time to cancel v_b (< 0) at full thrust, and the height it takes
        tb = brentq(lambda t: v_b + c * math.log(mass / (mass - q * t)) - gravity * t, 0.0,
                    (mass - limits.dry_mass) / q)
        m = mass - q * tb
        dh = v_b * tb - gravity * tb * tb / 2 + (c / q) * ((mass - m) - m * math.log(mass / m))
        return tb, dh

    def miss(tc: float) -> float:
        v_b = velocity - gravity * tc
        h_b = height + velocity * tc - gravity * tc * tc / 2
        return h_b + burn(v_b)[1]

    t_fall = (velocity + math.sqrt(velocity * velocity + 2 * gravity * height)) / gravity
    tc = brentq(miss, 0.0, t_fall)
    tb, _ = burn(velocity - gravity * tc)
    return q * tb, tc + tb
