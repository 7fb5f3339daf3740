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

Solver: cvxpy with Clarabel (an interior-point conic solver, installed with the project): the
problem is a second-order cone programme, which OSQP (a QP solver) cannot take.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np


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
class DescentProblem:
    """From ``(position_L, velocity_L, mass)`` to rest at ``target_L`` (m, m/s, kg).

    Local frame: origin on the surface below the target, z up (altitude), x and y horizontal.
    With ``free_horizontal`` only the target's altitude binds: the descent ends at rest at that
    altitude wherever it is cheapest (a hover, not a landing spot); the glide slope then has no apex
    and is not applied.
    """

    position_L: np.ndarray
    velocity_L: np.ndarray
    mass: float
    gravity: float
    limits: DescentLimits
    target_L: np.ndarray = field(default_factory=lambda: np.zeros(3))
    free_horizontal: bool = False

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
        cons = [
            r[0] == problem.position_L, v[0] == problem.velocity_L, z[0] == math.log(problem.mass),
            (r[N, 2] == problem.target_L[2]) if problem.free_horizontal else (r[N] == problem.target_L),
            v[N] == 0,
            r[1:] == r[:-1] + self.dt * v[:-1] + self.sixth_dt2 * (2 * u[:-1] + u[1:])
            + self.half_dt2 * (ones @ g[None, :]),
            v[1:] == v[:-1] + self.dt / 2 * (u[:-1] + u[1:]) + self.dt * (ones @ g[None, :]),
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
        self.program = cp.Problem(cp.Maximize(z[N]), cons)

    def solve(self, final_time: float, passes: int = 4) -> DescentSolution | None:
        import cvxpy as cp

        if not (final_time > 0):
            raise GuidanceError(f"final_time must be positive, got {final_time}")
        lim, N, m0 = self.problem.limits, self.N, self.problem.mass
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
        best: float | None = None
        for _ in range(passes):
            self.mu_max.value = lim.rho_max * np.exp(-z_ref)
            self.mu_max_offset.value = self.mu_max.value * (1 + z_ref)
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
            if best is not None and abs(zN - best) < 1e-10:
                break
            best, z_ref = zN, np.array(self.z.value)
        mass = np.exp(self.z.value)
        thrust = self.u.value * mass[:, None]
        return DescentSolution(t=t, position_L=np.array(self.r.value), velocity_L=np.array(self.v.value),
                               mass=mass, thrust_L=thrust, fuel=float(m0 - mass[-1]),
                               final_time=float(final_time), solve_count=1)


def solve_fixed_time(problem: DescentProblem, final_time: float, steps: int = 60) -> DescentSolution | None:
    """The minimum-fuel descent lasting exactly ``final_time`` s, or None when none is feasible."""
    return _FixedTimeProgram(problem, steps).solve(final_time)


def solve(problem: DescentProblem, steps: int = 60, t_bounds: tuple[float, float] | None = None,
          t_tol: float = 1e-5) -> DescentSolution:
    """The minimum-fuel descent with free final time (golden-section search on ``t_f``).

    ``t_bounds`` defaults to ``[t_lo, t_hi]`` with ``t_lo`` the time to cancel the speed at full
    thrust and ``t_hi`` the longest burn the fuel allows while hovering (their eq 45-46 bracket).
    Raises :class:`GuidanceError` when no final time in the bracket is feasible.
    """
    lim = problem.limits
    m0 = problem.mass
    if t_bounds is None:
        speed = float(np.linalg.norm(problem.velocity_L))
        t_lo = max(1e-2, speed * m0 / lim.rho_max) * 0.5
        t_hi = (m0 - lim.dry_mass) / (lim.alpha * max(lim.rho_min, m0 * problem.gravity * 0.5)) * 1.5
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
    grid = np.linspace(lo, hi, 9)
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
    best = min((tf for tf in cache if cache[tf] is not None), key=lambda tf: cache[tf].fuel)  # type: ignore[union-attr]
    sol = cache[best]
    assert sol is not None
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
