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
``sigma``). Minimising fuel is maximising ``z(t_f)``. The final time is free: a golden-section
search on ``t_f`` (the optimum fuel is unimodal in ``t_f``, their section IV.C).

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

Solver: cvxpy with Clarabel (an interior-point conic solver, installed with the project): the
problem is a second-order cone programme, which OSQP (a QP solver) cannot take.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: [m/s] floor of the airspeed the drag's Jacobian divides by: finite at rest in the air, where the
#: quadratic drag's derivative is zero anyway
MIN_AIRSPEED = 1e-9
#: [-] weight of the strictly convex touch on the thrust's energy (dt-weighted; ~1e-6 of the fuel):
#: makes the optimum unique so the drag's fixed-point iteration converges
STRICT_CONVEXITY = 1e-8
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
#: [-] margin on the bracket's upper end, the burn the fuel allows at the larger of the least thrust
#: and half the weight (their eq 46): the golden-section search needs a bracket that holds the optimum
BRACKET_MARGIN = 1.5


class GuidanceError(ValueError):
    """A guidance problem with bad inputs, or one with no feasible solution; the message says which."""


@dataclass(frozen=True)
class DescentLimits:
    """The vehicle seen as a point mass in the powered phase (SI units).

    rho_max, rho_min : total thrust magnitude bounds [N] (``rho_min`` 0 when the throttles can be off).
    alpha : fuel mass per impulse [kg/(N s)] = 1 / exhaust speed.
    dry_mass : mass below which there is no fuel [kg].
    max_tilt : largest angle between thrust and the local vertical [rad].
    glide_slope : smallest elevation of the vehicle seen from the target [rad]; 0 for none.
    """

    rho_max: float
    alpha: float
    dry_mass: float
    rho_min: float = 0.0
    max_tilt: float = math.pi / 2
    glide_slope: float = 0.0

    def __post_init__(self) -> None:
        if not (self.rho_max > 0 and math.isfinite(self.rho_max)):
            raise GuidanceError(f"rho_max must be a positive thrust in N, got {self.rho_max}")
        if not (0 <= self.rho_min < self.rho_max):
            raise GuidanceError(f"rho_min must be in [0, rho_max), got {self.rho_min}")
        if not (self.alpha > 0 and self.dry_mass > 0):
            raise GuidanceError(f"alpha and dry_mass must be positive, got {self.alpha}, {self.dry_mass}")
        if not (0 < self.max_tilt <= math.pi / 2):
            raise GuidanceError(f"max_tilt must be in (0, pi/2] rad, got {self.max_tilt}")
        if not (0 <= self.glide_slope < math.pi / 2):
            raise GuidanceError(f"glide_slope must be in [0, pi/2) rad, got {self.glide_slope}")


@dataclass(frozen=True)
class DragModel:
    """Aerodynamic drag of the point mass: ``F = -k rho(h) |v - w| (v - w)`` (SI units).

    k : ``sum 1/2 Cd A`` over the bodies that pull (sphere, open chute) [m^2].
    surface_density : [kg/m^3]; scale_height : [m] (exponential atmosphere, altitude = local z).
    wind_L : steady wind ``w`` in the local frame [m/s] (none by default).
    """

    k: float
    surface_density: float
    scale_height: float
    wind_L: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (self.k >= 0 and self.surface_density >= 0 and self.scale_height > 0):
            raise GuidanceError(f"drag: need k >= 0, surface_density >= 0, scale_height > 0; got {self}")

    def acceleration(self, position_L: np.ndarray, velocity_L: np.ndarray, mass: np.ndarray) -> np.ndarray:
        """``a_D`` at each row of ``(position, velocity, mass)`` [m/s^2]."""
        rho = self.surface_density * np.exp(-np.asarray(position_L)[:, 2] / self.scale_height)
        v = np.asarray(velocity_L) - np.asarray(self.wind_L)  # airspeed
        return -(self.k * rho / mass * np.linalg.norm(v, axis=1))[:, None] * v

    def jacobian(self, position_L: np.ndarray, velocity_L: np.ndarray, mass: np.ndarray) -> np.ndarray:
        """``d a_D / d v`` at each row, shape (n, 3, 3) [1/s]."""
        rho = self.surface_density * np.exp(-np.asarray(position_L)[:, 2] / self.scale_height)
        v = np.asarray(velocity_L) - np.asarray(self.wind_L)
        s = np.maximum(np.linalg.norm(v, axis=1), MIN_AIRSPEED)
        return -(self.k * rho / mass)[:, None, None] * (s[:, None, None] * np.eye(3)
                                                       + v[:, :, None] * v[:, None, :] / s[:, None, None])


def drag_up(drag: DragModel | None, position_L: np.ndarray, velocity_L: np.ndarray, mass: float) -> float:
    """The drag acceleration along up [m/s^2, local ENU] at one state; 0 without a drag model."""
    if drag is None:
        return 0.0
    return float(drag.acceleration(np.asarray(position_L, float)[None, :], np.asarray(velocity_L, float)[None, :],
                                   np.array([mass]))[0, 2])


@dataclass(frozen=True)
class DescentProblem:
    """From ``(position_L, velocity_L, mass)`` to rest at ``target_L`` (m, m/s, kg).

    Local frame: origin on the surface below the target, z up (altitude), x and y horizontal.
    With ``free_horizontal`` only the target's altitude binds: the descent ends at rest at that
    altitude wherever it is cheapest (a hover, not a landing spot); the glide slope then has no apex
    and is not applied. ``end_band`` [m] and ``end_speed`` [m/s] relax the end to a tolerance: within
    ``end_band`` of the target's altitude and under ``end_speed`` (both convex; 0: exactly there, at
    rest), the end of a flight judged by a hover band (docs/deorbit.md, "Measured results").
    """

    position_L: np.ndarray
    velocity_L: np.ndarray
    mass: float
    gravity: float
    limits: DescentLimits
    target_L: np.ndarray = field(default_factory=lambda: np.zeros(3))
    free_horizontal: bool = False
    drag: DragModel | None = None
    end_band: float = 0.0
    end_speed: float = 0.0

    def __post_init__(self) -> None:
        for name in ("position_L", "velocity_L", "target_L"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise GuidanceError(f"{name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, a)
        if not (self.mass > self.limits.dry_mass):
            raise GuidanceError(f"mass {self.mass} kg must exceed the dry mass {self.limits.dry_mass} kg")
        if not (self.gravity > 0):
            raise GuidanceError(f"gravity must be positive (m/s^2), got {self.gravity}")
        for name in ("end_band", "end_speed"):
            if not (getattr(self, name) >= 0):
                raise GuidanceError(f"{name} must be >= 0, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class DescentSolution:
    """A discretised optimal descent: ``N + 1`` nodes at ``t``; ``thrust_L`` at the nodes (linear between)."""

    t: np.ndarray  # (N+1,) s
    position_L: np.ndarray  # (N+1, 3) m
    velocity_L: np.ndarray  # (N+1, 3) m/s
    mass: np.ndarray  # (N+1,) kg
    thrust_L: np.ndarray  # (N+1, 3) N
    fuel: float  # kg
    final_time: float  # s
    solve_count: int  # convex solves the final-time search took

    @property
    def thrust_magnitude(self) -> np.ndarray:
        return np.linalg.norm(self.thrust_L, axis=1)


class _FixedTimeProgram:
    """The convex programme for one problem and step count, built once (cvxpy parameters, DPP).

    Parameters that change between solves: the step (final time), and the expansion point of the
    thrust bounds. The upper bound ``rho_max e^-z`` is convex in ``z``, so its tangent at ``z_ref``
    lies below it: every solution is feasible for the true bound, and re-solving with ``z_ref`` at
    the last solution's log-mass (successive convexification, :meth:`solve`) makes it tight where
    it matters. Acikmese and Ploen expand about the flat-out burn ``z0(t)`` once (their eq 19-20);
    that is conservative by ``(z - z0)^2 / 2`` after a coast, a few per cent of thrust.
    """

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
            # A strictly convex touch (1e-8 of the acceleration's energy, dt-weighted: ~1e-6 of the
            # fuel here) makes the optimum unique, so the drag's fixed-point iteration converges
            # instead of wandering over a flat face of optima (a coast's timing, a hover's place).
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

    def solve(self, final_time: float, passes: int | None = None) -> DescentSolution | None:
        """The optimum for ``final_time`` s, or None when infeasible. ``passes`` bounds the
        re-linearisations (default 4 without drag: the thrust bound's expansion converges in 2-3;
        30 with drag, whose iteration settles in 3-15 passes where it settles at all (measured on the
        de-orbit handovers; a final time that has not settled by then counts as infeasible))."""
        import cvxpy as cp

        if not (final_time > 0):
            raise GuidanceError(f"final_time must be positive, got {final_time}")
        lim, N, m0 = self.problem.limits, self.N, self.problem.mass
        drag = self.problem.drag
        passes = passes if passes is not None else (4 if drag is None else 30)
        dt = final_time / N
        self.dt.value, self.half_dt2.value, self.alpha_dt.value = dt, dt * dt / 2, lim.alpha * dt
        self.sixth_dt2.value = dt * dt / 6
        t = np.arange(N + 1) * dt
        # First expansion point: the flat-out burn, clipped at the dry mass past burn-out.
        z_flat = np.log(np.maximum(m0 - lim.alpha * lim.rho_max * t, lim.dry_mass))
        if lim.rho_min > 0:
            self.z0.value = z_flat
            self.mu_min.value = lim.rho_min * np.exp(-z_flat)
        z_ref = z_flat
        if drag is not None:
            # First drag reference: the velocity falling linearly to rest, the height following it.
            p0, v0 = self.problem.position_L, self.problem.velocity_L
            v_ref = v0[None, :] * (1 - t / final_time)[:, None]
            r_ref = p0[None, :] + v0[None, :] * (t - t * t / (2 * final_time))[:, None]
            trust = TRUST_WIDTH * (1.0 + float(np.linalg.norm(v0)))  # [m/s]: wide; the relaxation below damps
            relax, prev_step = 1.0, None
        best: float | None = None
        converged = drag is None
        for _ in range(passes):
            self.mu_max.value = lim.rho_max * np.exp(-z_ref)
            self.mu_max_offset.value = self.mu_max.value * (1 + z_ref)
            if drag is not None:
                m_ref = np.exp(z_ref)
                J = drag.jacobian(r_ref, v_ref, m_ref)
                self.drag_c0.value = drag.acceleration(r_ref, v_ref, m_ref) - np.einsum("kij,kj->ki", J, v_ref)
                for i in range(3):
                    for j in range(3):
                        self.drag_J[i][j].value = J[:, i, j]
                self.v_ref.value, self.trust.value = v_ref, trust
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
            zN = float(self.z.value[-1])
            if drag is None:
                if best is not None and abs(zN - best) < LOG_MASS_TOLERANCE:
                    break
                best, z_ref = zN, np.array(self.z.value)
                continue
            v_sol = np.array(self.v.value)
            step = float(np.max(np.abs(v_sol - v_ref)))
            # Converged when the drag the programme flew (linearised) is the true drag of its own
            # trajectory to 1e-2 m/s^2 (0.3 % of g: ~0.2 m/s over a 20-s burn, ~0.3 % of its fuel) and the fuel between passes agrees to 1e-3 of the
            # fuel burnt: the passes scatter by ~1e-4 (the optimum is flat along some directions, a
            # coast node's timing, and the solver returns any point of that face), and a yardstick
            # for a 3 % criterion needs 0.1 %.
            lin = self.drag_c0.value + np.einsum("kij,kj->ki", J, v_sol)
            residual = float(np.max(np.abs(drag.acceleration(np.array(self.r.value), v_sol, np.exp(self.z.value)) - lin)))
            if residual < DRAG_RESIDUAL and best is not None and abs(math.exp(zN) - math.exp(best)) < FUEL_AGREEMENT * (m0 - math.exp(zN)):
                converged = True
                break
            # Fixed-point iteration on the drag's reference, relaxed (Krasnoselskii-Mann averaging)
            # once it stops contracting: undamped, it settles into a 2-cycle when the burn's start
            # moves by a node between passes.
            if prev_step is not None and step > CONTRACTION * prev_step:
                relax = max(0.5 * relax, MIN_RELAXATION)
            prev_step = step
            v_ref = v_ref + relax * (v_sol - v_ref)
            r_ref = r_ref + relax * (np.array(self.r.value) - r_ref)
            z_ref = z_ref + relax * (np.array(self.z.value) - z_ref)
            best = zN
        if not converged:
            return None  # the linearised drag never settled: no trustworthy optimum at this final time
        mass = np.exp(self.z.value)
        thrust = self.u.value * mass[:, None]
        return DescentSolution(t=t, position_L=np.array(self.r.value), velocity_L=np.array(self.v.value),
                               mass=mass, thrust_L=thrust, fuel=float(m0 - mass[-1]),
                               final_time=float(final_time), solve_count=1)


def solve_fixed_time(problem: DescentProblem, final_time: float, steps: int = 60) -> DescentSolution | None:
    """The minimum-fuel descent lasting exactly ``final_time`` s, or None when none is feasible."""
    return _FixedTimeProgram(problem, steps).solve(final_time)


def solve(problem: DescentProblem, steps: int = 60, t_bounds: tuple[float, float] | None = None,
          t_tol: float = FINAL_TIME_TOLERANCE) -> DescentSolution:
    """The minimum-fuel descent with free final time (golden-section search on ``t_f``).

    ``t_bounds`` defaults to ``[t_lo, t_hi]`` with ``t_lo`` the time to cancel the speed at full
    thrust and ``t_hi`` the longest burn the fuel allows while hovering (their eq 45-46 bracket).
    Raises :class:`GuidanceError` when no final time in the bracket is feasible.
    """
    lim = problem.limits
    m0 = problem.mass
    if t_bounds is None:
        speed = float(np.linalg.norm(problem.velocity_L))
        t_lo = max(MIN_FINAL_TIME, speed * m0 / lim.rho_max) * 0.5
        t_hi = (m0 - lim.dry_mass) / (lim.alpha * max(lim.rho_min, m0 * problem.gravity * 0.5)) * BRACKET_MARGIN
        t_bounds = (t_lo, max(t_hi, 2 * t_lo))
    lo, hi = map(float, t_bounds)
    count = 0
    cache: dict[float, DescentSolution | None] = {}
    program = _FixedTimeProgram(problem, steps)

    def fuel(tf: float) -> float:
        nonlocal count
        if tf not in cache:
            count += 1
            cache[tf] = program.solve(tf)
        sol = cache[tf]
        return math.inf if sol is None else sol.fuel

    # Infeasible final times are +inf; coarse scan first so the golden section starts inside the
    # feasible, unimodal interval.
    # With drag the feasible final times are a narrow band near the short end (under the chute the
    # lander cannot fall faster than its terminal speed, and a long descent hovers at a loss), and a
    # final time whose drag iteration does not settle counts as infeasible: a geometric grid.
    grid = np.geomspace(lo, hi, 13) if problem.drag is not None else np.linspace(lo, hi, 9)
    fuels = [fuel(float(tf)) for tf in grid]
    k = int(np.argmin(fuels))
    if not math.isfinite(fuels[k]):
        raise GuidanceError(f"no feasible descent with final time in [{lo:.2f}, {hi:.2f}] s "
                            f"(too little fuel or thrust for this handover state)")
    a, b = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, len(grid) - 1)])
    invphi = (math.sqrt(5) - 1) / 2
    c, d = b - invphi * (b - a), a + invphi * (b - a)
    while b - a > t_tol * max(1.0, a):
        if fuel(c) <= fuel(d):
            b, d = d, c
            c = b - invphi * (b - a)
        else:
            a, c = c, d
            d = a + invphi * (b - a)
    solved = {tf: s for tf, s in cache.items() if s is not None}
    best = min(solved, key=lambda tf: solved[tf].fuel)
    sol = solved[best]
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
