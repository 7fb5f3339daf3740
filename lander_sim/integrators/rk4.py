"""Classical fourth-order Runge-Kutta on the first-order form of the dynamics."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lander_sim.integrators.base import check_dt, clamp_fuel, derivative, renormalise_quaternion
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import N_STATE


@dataclass
class RK4:
    """Classical RK4 on ``y' = f(t, y)`` (:func:`lander_sim.integrators.base.derivative`).

    Four evaluations per step, fourth order. The quaternion is advanced as a plain vector by
    eq 14, so ``|q|`` drifts by ``O(dt^5)`` per step; ``renormalise`` (default on) projects it
    back after each step (seed 1 task 3). Euler-mode scenes use eq 5 for ``E'``.

    With ``compiled`` (default) a model that has a compiled form
    (:func:`lander_sim.fast.rk_kernels.compiled_model`: the standard lander models, quaternion or
    Euler-angle attitude) is stepped by :func:`~lander_sim.fast.rk_kernels.rk4_steps`, the same
    arithmetic in numba;
    ``compiled=False`` keeps this numpy code, the reference (they agree to ~1e-15 relative).
    """

    renormalise: bool = True
    compiled: bool = True
    name: str = "rk4"
    order: int = 4
    _k: np.ndarray = field(default_factory=lambda: np.zeros((4, N_STATE)), repr=False)
    _tmp: np.ndarray = field(default_factory=lambda: np.zeros(N_STATE), repr=False)
    _acc: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        if self.compiled and _fast_step(dyn, y, dt, self.renormalise):
            return
        k, tmp, acc = self._k, self._tmp, self._acc
        h = 0.5 * dt
        derivative(dyn, t, y, k[0], acc)
        np.multiply(k[0], h, out=tmp)
        tmp += y
        derivative(dyn, t + h, tmp, k[1], acc)
        np.multiply(k[1], h, out=tmp)
        tmp += y
        derivative(dyn, t + h, tmp, k[2], acc)
        np.multiply(k[2], dt, out=tmp)
        tmp += y
        derivative(dyn, t + dt, tmp, k[3], acc)
        y += (dt / 6.0) * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])
        if self.renormalise and dyn.attitude == "quaternion":
            renormalise_quaternion(y)
        clamp_fuel(y)


def _fast_step(dyn: Dynamics, y: np.ndarray, dt: float, renormalise: bool) -> bool:
    """One compiled RK4 step if the model has a compiled form (and numba is there); False otherwise."""
    from lander_sim.fast import HAVE_NUMBA
    from lander_sim.fast.rk_kernels import compiled_model, rk4_steps

    cm = compiled_model(dyn) if HAVE_NUMBA else None
    if cm is None:
        return False
    thr, wind = cm.inputs()
    dyn.evaluations += rk4_steps(y, dt, 1, cm.params, cm.force, cm.torque, cm.burn, thr, wind, cm.translation, renormalise)
    return True
