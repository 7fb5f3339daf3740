"""The vehicle: mass properties and thruster geometry, all in the body frame.

Shared by the physics (thrust force and torque) and by control design
(``lander_autopilot.design``: B matrices from ``s_i = p_i x d_i``, eq 26 of the control reference).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Thruster:
    """One thruster.

    Attributes
    ----------
    position_B : ndarray (3,)
        Point of action p_i relative to the centre of mass, body frame [m].
    direction_B : ndarray (3,)
        Unit exhaust direction d_i, body frame; the force is ``-d_i t_i T_max`` (seed 1 task 2).
    max_thrust : float
        T_max [N].
    fuel_rate : float
        Fuel burn at full throttle [kg/s].
    enabled : bool
        A disabled thruster produces nothing whatever its throttle.
    """

    position_B: np.ndarray
    direction_B: np.ndarray
    max_thrust: float
    fuel_rate: float
    enabled: bool = True


@dataclass(frozen=True)
class Vehicle:
    """Mass properties and thrusters.

    Inertia is either fixed (``inertia_diag``, e.g. the rotor about its pivot)
    or proportional to the current mass (``gyration_sq``: ``I = m diag(k^2)``,
    the lander, whose inertia shrinks as fuel burns).
    """

    dry_mass: float
    fuel_capacity: float
    thrusters: tuple[Thruster, ...] = ()
    gyration_sq: tuple[float, float, float] | None = None
    inertia_diag: tuple[float, float, float] | None = None
    size: float = 1.0
    _s: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if (self.gyration_sq is None) == (self.inertia_diag is None):
            raise ValueError("give exactly one of gyration_sq (I = m k^2) or inertia_diag (fixed I)")
        s = np.array([np.cross(t.position_B, t.direction_B) for t in self.thrusters]).reshape(-1, 3)
        object.__setattr__(self, "_s", s)

    @property
    def n_thrusters(self) -> int:
        return len(self.thrusters)

    def mass(self, fuel: float) -> float:
        """Total mass [kg] with ``fuel`` kg in the tank."""
        return self.dry_mass + fuel

    def inertia(self, fuel: float) -> np.ndarray:
        """Principal moments ``(A, B, C)`` [kg m^2] about the body axes."""
        if self.inertia_diag is not None:
            return np.asarray(self.inertia_diag, dtype=float)
        return self.mass(fuel) * np.asarray(self.gyration_sq, dtype=float)

    def torque_arms(self) -> np.ndarray:
        """``s_i = p_i x d_i`` for every thruster, shape (N, 3) (eq 26 of the control reference)."""
        return self._s
