"""The integrator interface and the first-order form shared by the Runge-Kutta family."""
from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import ATT, EULER, FUEL, OMEGA_B, R_W, V_W


class IntegratorError(ValueError):
    """Bad integrator configuration: unknown name, unknown option or a non-positive step."""


def check_dt(dt: float) -> float:
    """Return ``dt`` as a float if it is a finite positive step [s]; else raise :class:`IntegratorError`."""
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise IntegratorError(f"time step dt must be a positive number of seconds, got {dt!r}") from None
    if not (value > 0.0 and math.isfinite(value)):
        raise IntegratorError(f"time step dt must be a positive, finite number of seconds, got {dt!r}")
    return value


class Integrator(Protocol):
    """A fixed-step method: advance ``y`` in place from ``t`` to ``t + dt``."""

    name: str
    #: Theoretical global order of accuracy (used by the convergence tests).
    order: int

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None: ...


def derivative(dyn: Dynamics, t: float, y: np.ndarray, out: np.ndarray, acc: np.ndarray) -> None:
    """First-order form ``y' = f(t, y)`` of the second-order dynamics.

    r' = v; v' = a_W; attitude' from eq 14 (quaternion) or eq 5 (ZXZ Euler);
    omega' from Euler's equations (eq 2, via ``dyn.accelerations``); fuel' = rate.
    ``acc`` is a (6,) scratch buffer.
    """
    dyn.accelerations(t, y, acc)
    if dyn.translation:
        out[R_W] = y[V_W]
        out[V_W] = acc[0:3]
    else:
        out[0:6] = 0.0
    w = y[OMEGA_B]
    if dyn.attitude == "quaternion":
        out[ATT] = rotation.quat_dot(y[ATT], w)
    else:
        out[EULER] = rotation.euler_rates_matrix(y[EULER]) @ w
        out[9] = 0.0
    out[OMEGA_B] = acc[3:6]
    out[FUEL] = dyn.fuel_rate(t, y)


def renormalise_quaternion(y: np.ndarray) -> None:
    """Project the attitude quaternion back onto |q| = 1 (seed 1 task 3)."""
    q = y[ATT]
    n = math.sqrt(float(q @ q))
    y[ATT] = q / n


def clamp_fuel(y: np.ndarray) -> None:
    """Fuel cannot go negative: the tank runs dry inside the step at the latest."""
    if y[FUEL] < 0.0:
        y[FUEL] = 0.0
