"""Velocity Verlet, exactly as section 5 of the dynamics reference and its skeleton program."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lander_sim.integrators.base import check_dt, clamp_fuel, renormalise_quaternion
from lander_sim.physics import rotation
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import ATT, EULER, FUEL, OMEGA_B, R_W, V_W


@dataclass
class VelocityVerlet:
    """Velocity Verlet (seed 1, section 5), translation and rotation together.

    1. ``v(t+dt/2) = v(t) + a(t) dt/2`` (and the same for ``omega``);
    2. ``r(t+dt) = r(t) + v(t+dt/2) dt``; the attitude moves with the half-step rate:
       quaternion ``q + q'(q, omega(t+dt/2)) dt`` (eq 14), then renormalised if
       ``renormalise`` (seed 1 task 3); Euler angles ``E + E' dt + E'' dt^2/2`` (eq 5, 6, 7);
    3. ``a(t+dt)`` estimated at the new position with the velocity estimate
       ``v + a dt`` (velocity-dependent forces need one; the skeleton uses the same for omega);
    4. ``v(t+dt) = v(t+dt/2) + a(t+dt) dt/2``.

    Two acceleration evaluations per step; second order. With ``compiled`` (default) a model with
    a compiled form (:func:`lander_sim.fast.rk_kernels.compiled_model`: quaternion or Euler
    angles, free or on a fixed pivot) is stepped by :func:`lander_sim.fast.lander_kernel.verlet_steps`,
    the same arithmetic in numba; ``compiled=False`` keeps this numpy code, the reference.
    """

    renormalise: bool = True
    compiled: bool = True
    name: str = "verlet"
    order: int = 2
    _a0: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)
    _a1: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)
    _est: np.ndarray = field(default_factory=lambda: np.zeros(14), repr=False)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        if self.compiled and _fast_step(dyn, y, dt, self.renormalise):
            return
        a0, a1, est = self._a0, self._a1, self._est
        dyn.accelerations(t, y, a0)
        fuel_rate = dyn.fuel_rate(t, y)
        h = 0.5 * dt
        w = y[OMEGA_B]
        w_half = w + h * a0[3:6]
        if dyn.attitude == "quaternion":
            q = y[ATT]
            y[ATT] = q + rotation.quat_dot(q, w_half) * dt
            if self.renormalise:
                renormalise_quaternion(y)
        else:
            E = y[EULER]
            y[EULER] = E + rotation.euler_rates_matrix(E) @ w * dt + 0.5 * dt * dt * rotation.euler_ddot(E, w, a0[3:6])
        if dyn.translation:
            v_half = y[V_W] + h * a0[0:3]
            y[R_W] = y[R_W] + v_half * dt
        y[FUEL] += fuel_rate * dt
        clamp_fuel(y)
        # Step 3: accelerations at the new position with predicted velocities.
        est[:] = y
        est[OMEGA_B] = w + dt * a0[3:6]
        if dyn.translation:
            est[V_W] = y[V_W] + dt * a0[0:3]
        dyn.accelerations(t + dt, est, a1)
        y[OMEGA_B] = w_half + h * a1[3:6]
        if dyn.translation:
            y[V_W] = v_half + h * a1[0:3]


def _fast_step(dyn: Dynamics, y: np.ndarray, dt: float, renormalise: bool) -> bool:
    """One compiled Verlet step if the model has a compiled form (and numba is there); False otherwise."""
    from lander_sim.fast import HAVE_NUMBA
    from lander_sim.fast.lander_kernel import verlet_steps
    from lander_sim.fast.rk_kernels import compiled_model

    cm = compiled_model(dyn) if HAVE_NUMBA else None
    if cm is None:
        return False
    thr, wind = cm.inputs()
    taken = verlet_steps(y, np.empty(14), 1, dt, cm.verlet_params(renormalise), cm.force, cm.torque, cm.burn, thr, wind, 0.0)
    dyn.evaluations += 2 * taken
    return True
