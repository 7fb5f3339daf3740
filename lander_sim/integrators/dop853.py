"""Dormand-Prince 8(5,3), high order with adaptive steps, as scipy's ``solve_ivp(method="DOP853")``.

Hairer, Norsett & Wanner, *Solving ODEs I* (2nd ed.), II.5 (the method) and II.4 (step-size
control). Each ``step(dyn, t, y, dt)`` integrates ``[t, t + dt]`` in one adaptive run under
local error control (``rtol``, ``atol``), as ``solve_ivp`` does over that span. A model with a
compiled form runs in numba (:func:`lander_sim.fast.rk_kernels.dop853_span`, which takes scipy's
steps); otherwise, or with ``compiled=False``, scipy's own DOP853 integrates the numpy first-order
form (:func:`lander_sim.integrators.base.derivative`): the reference.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lander_sim.integrators.base import (
    IntegratorError,
    check_dt,
    clamp_fuel,
    derivative,
    renormalise_quaternion,
)
from lander_sim.physics.dynamics_protocol import Dynamics


@dataclass
class DOP853:
    """Eighth-order Dormand-Prince with scipy's error control; quaternion renormalised after each call.

    Attributes
    ----------
    rtol, atol : float
        Relative and absolute tolerance of each internal step's local error estimate.
    renormalise : bool
        Project the quaternion back onto ``|q| = 1`` after each call.
    compiled : bool
        Use the compiled kernel when the model has a compiled form (False: scipy, the reference).
    accepted, rejected : int
        Internal steps of the compiled runs (scipy does not report them).
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    renormalise: bool = True
    compiled: bool = True
    name: str = "dop853"
    order: int = 8
    accepted: int = 0
    rejected: int = 0
    _acc: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)

    def __post_init__(self) -> None:
        for key in ("rtol", "atol"):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                raise IntegratorError(f"dop853 integrator option {key!r} must be a positive number, got {value!r}")

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        if not (self.compiled and self._step_compiled(dyn, y, dt)):
            self._step_scipy(dyn, t, y, dt)
        if self.renormalise and dyn.attitude == "quaternion":
            renormalise_quaternion(y)
        clamp_fuel(y)

    def _step_compiled(self, dyn: Dynamics, y: np.ndarray, dt: float) -> bool:
        from lander_sim.fast import HAVE_NUMBA
        from lander_sim.fast.rk_kernels import (
            compiled_model,
            dop853_span,
            dop853_tableau,
        )

        cm = compiled_model(dyn) if HAVE_NUMBA else None
        if cm is None:
            return False
        thr, wind = cm.inputs()
        stats = np.zeros(3)
        status = dop853_span(y, dt, self.rtol, self.atol, cm.params, cm.force, cm.torque, cm.burn, thr, wind,
                             cm.translation, *dop853_tableau(), stats)
        self.accepted += int(stats[0])
        self.rejected += int(stats[1])
        dyn.evaluations += int(stats[2])
        if status != 0:
            raise FloatingPointError("dop853: step size became too small")
        return True

    def _step_scipy(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        from scipy.integrate import solve_ivp

        acc = self._acc

        def f(tt: float, yy: np.ndarray) -> np.ndarray:
            out = np.empty_like(yy)
            derivative(dyn, tt, yy, out, acc)
            return out

        sol = solve_ivp(f, (t, t + dt), y.copy(), method="DOP853", rtol=self.rtol, atol=self.atol)
        if not sol.success:
            raise FloatingPointError(f"dop853 (scipy): {sol.message}")
        y[:] = sol.y[:, -1]
