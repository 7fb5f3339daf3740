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
    """

    renormalise: bool = True
    name: str = "rk4"
    order: int = 4
    _k: np.ndarray = field(default_factory=lambda: np.zeros((4, N_STATE)), repr=False)
    _tmp: np.ndarray = field(default_factory=lambda: np.zeros(N_STATE), repr=False)
    _acc: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
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
