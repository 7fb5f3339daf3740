"""Adaptive embedded Runge-Kutta: Dormand-Prince 5(4) with error control (Hairer, Norsett & Wanner, II.4-5)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from lander_sim.integrators.base import (
    IntegratorError,
    check_dt,
    clamp_fuel,
    derivative,
    renormalise_quaternion,
)
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import N_STATE

# Dormand-Prince 5(4) tableau (Dormand & Prince 1980). Row i gives the stage weights a_ij.
_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
#: Difference between the 5th-order weights (= last row of _A) and the embedded 4th-order ones.
_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)

_SAFETY = 0.9
_FAC_MIN = 0.2
_FAC_MAX = 5.0
_MAX_INTERNAL_STEPS = 1_000_000


@dataclass
class AdaptiveDormandPrince:
    """Dormand-Prince 5(4) with per-step error control, landing exactly on each output instant.

    ``step(dyn, t, y, dt)`` advances ``y`` from ``t`` to exactly ``t + dt`` with as many internal
    steps as the tolerance needs. The last internal step is shortened to hit ``t + dt`` (so output
    at the fixed publish instants costs no dense-output interpolation error), and the *unclipped*
    step size is kept for the next call. Inputs are constant over a call, so FSAL (the last stage
    of one internal step is the first of the next) is used inside a call but never across calls.

    Error norm (Hairer-Norsett-Wanner II eq 4.11): ``err = rms_i(e_i / (atol + rtol max(|y_i|, |y_new_i|)))``;
    a step is accepted when ``err <= 1`` and the next size is ``h * clip(0.9 err^(-1/5), 0.2, 5)``.

    Attributes
    ----------
    rtol, atol : float
        Relative and absolute tolerance (absolute in SI units of each state component).
    renormalise : bool
        Project the quaternion back onto ``|q| = 1`` after each call (not inside one: that
        would break FSAL). The drift it removes is of the order of the tolerance.
    accepted, rejected : int
        Internal steps accepted / rejected since construction or :meth:`reset`.
    last_error : float
        Normalised error estimate of the last accepted internal step (``<= 1``).
    max_error : float
        Largest accepted normalised error estimate so far.
    observer : callable or None
        Called as ``observer(t, y_start, y_end, h)`` after each accepted internal step (for
        checks of the local error and for plots of the step size); None costs nothing.
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    renormalise: bool = True
    first_step: float | None = None
    observer: Callable[[float, np.ndarray, np.ndarray, float], None] | None = field(default=None, repr=False)
    name: str = "adaptive"
    order: int = 5
    accepted: int = 0
    rejected: int = 0
    last_error: float = 0.0
    max_error: float = 0.0
    _h: float | None = field(default=None, repr=False)
    _k: np.ndarray = field(default_factory=lambda: np.zeros((7, N_STATE)), repr=False)
    _tmp: np.ndarray = field(default_factory=lambda: np.zeros(N_STATE), repr=False)
    _ynew: np.ndarray = field(default_factory=lambda: np.zeros(N_STATE), repr=False)
    _err: np.ndarray = field(default_factory=lambda: np.zeros(N_STATE), repr=False)
    _acc: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)

    def __post_init__(self) -> None:
        for key in ("rtol", "atol"):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and value > 0.0 and math.isfinite(value)):
                raise IntegratorError(f"adaptive integrator option {key!r} must be a positive number, got {value!r}")
        if self.rtol < 1e-14:
            raise IntegratorError(f"adaptive integrator option 'rtol' must be >= 1e-14 (round-off), got {self.rtol!r}")
        if self.first_step is not None:
            check_dt(self.first_step)
        self._h = self.first_step

    def reset(self) -> None:
        """Forget the step size and zero the counters (e.g. after a state jump)."""
        self._h = self.first_step
        self.accepted = self.rejected = 0
        self.last_error = self.max_error = 0.0

    def _initial_step(self, y: np.ndarray, f0: np.ndarray, dt: float) -> float:
        # First guess of HNW II.4 (without the second-derivative refinement): h = 0.01 |y| / |f|.
        scale = self.atol + self.rtol * np.abs(y)
        d0 = math.sqrt(float(np.mean((y / scale) ** 2)))
        d1 = math.sqrt(float(np.mean((f0 / scale) ** 2)))
        h = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        return min(h, dt)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        k, tmp, ynew, err, acc = self._k, self._tmp, self._ynew, self._err, self._acc
        t_end = t + dt
        derivative(dyn, t, y, k[0], acc)
        h = self._h if self._h is not None else self._initial_step(y, k[0], dt)
        for _ in range(_MAX_INTERNAL_STEPS):
            remaining = t_end - t
            # Stretch the last step by up to 1 % rather than leave a sliver behind.
            last = 1.01 * h >= remaining
            hs = remaining if last else h
            for i in range(1, 7):
                np.copyto(tmp, y)
                for j, a in enumerate(_A[i]):
                    if a != 0.0:
                        tmp += (hs * a) * k[j]
                if i < 6:
                    derivative(dyn, t + _C[i] * hs, tmp, k[i], acc)
            np.copyto(ynew, tmp)  # the 5th-order solution is stage 7's argument
            derivative(dyn, t + hs, ynew, k[6], acc)
            err.fill(0.0)
            for j, e in enumerate(_E):
                if e != 0.0:
                    err += (hs * e) * k[j]
            scale = self.atol + self.rtol * np.maximum(np.abs(y), np.abs(ynew))
            en = math.sqrt(float(np.mean((err / scale) ** 2)))
            if en <= 1.0:
                self.accepted += 1
                self.last_error = en
                self.max_error = max(self.max_error, en)
                if self.observer is not None:
                    self.observer(t, y, ynew, hs)
                y[:] = ynew
                t = t_end if last else t + hs
                k[0] = k[6]  # FSAL
                fac = _FAC_MAX if en == 0.0 else min(_FAC_MAX, max(_FAC_MIN, _SAFETY * en ** -0.2))
                # A clipped last step must not shrink the natural step kept for the next call.
                h = max(h, hs * fac) if fac >= 1.0 else hs * fac
                if last:
                    break
            else:
                self.rejected += 1
                h = hs * max(_FAC_MIN, _SAFETY * en ** -0.2)
                if h < 1e-14 * max(1.0, abs(t)):
                    raise FloatingPointError(f"adaptive step size underflow at t={t:.6g} s (h={h:.3g} s)")
        else:
            raise FloatingPointError(f"adaptive integrator exceeded {_MAX_INTERNAL_STEPS} internal steps in one call")
        self._h = h
        if self.renormalise and dyn.attitude == "quaternion":
            renormalise_quaternion(y)
        clamp_fuel(y)
