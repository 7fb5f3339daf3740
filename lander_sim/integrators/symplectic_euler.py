"""Semi-implicit (symplectic) Euler: kick with the old state, drift with the new velocities."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lander_sim.integrators.base import check_dt, clamp_fuel, renormalise_quaternion
from lander_sim.physics import rotation
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import ATT, EULER, FUEL, OMEGA_B, R_W, V_W


@dataclass
class SymplecticEuler:
    """Semi-implicit Euler, translation and rotation together; first order, one evaluation per step.

    ``v(t+dt) = v + a(t, y) dt`` and ``omega(t+dt) = omega + omega'(t, y) dt`` (eq 7 of the
    control reference, eq 2 of the dynamics reference), then the positions move with the *new*
    rates: ``r += v(t+dt) dt``; quaternion ``q += q'(q, omega(t+dt)) dt`` (eq 14), renormalised
    if ``renormalise``; Euler angles ``E += J(E) omega(t+dt) dt`` (eq 5).

    For a separable Hamiltonian (gravity alone) the translational map is symplectic, so the
    energy error of a bound orbit oscillates instead of drifting; with velocity-dependent forces
    (drag) or the rotational equations it is just a first-order method.
    """

    renormalise: bool = True
    name: str = "symplectic-euler"
    order: int = 1
    _a: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        a = self._a
        dyn.accelerations(t, y, a)
        fuel_rate = dyn.fuel_rate(t, y)
        y[OMEGA_B] += dt * a[3:6]
        w = y[OMEGA_B]
        if dyn.attitude == "quaternion":
            y[ATT] += dt * rotation.quat_dot(y[ATT], w)
            if self.renormalise:
                renormalise_quaternion(y)
        else:
            y[EULER] += dt * (rotation.euler_rates_matrix(y[EULER]) @ w)
        if dyn.translation:
            y[V_W] += dt * a[0:3]
            y[R_W] += dt * y[V_W]
        y[FUEL] += fuel_rate * dt
        clamp_fuel(y)
