"""The minimum-fuel descent's problem and solution types (SI units, local frame z up).

Shared by the programme's two back-ends (:mod:`.descent_conic`, the flown one; the cvxpy
cross-check in :mod:`.fuel_optimal`) and the search over the final time (:mod:`.fuel_optimal`,
which re-exports these names: the module docstring there gives the method and its papers).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: [m/s] floor of the airspeed the drag's Jacobian divides by: finite at rest in the air, where the
#: quadratic drag's derivative is zero anyway
MIN_AIRSPEED = 1e-9
#: [-] weight of the strictly convex touch on the thrust's energy (dt-weighted; ~1e-6 of the fuel):
#: makes the optimum unique so the drag's fixed-point iteration converges
STRICT_CONVEXITY = 1e-8


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
