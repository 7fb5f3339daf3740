"""Numerical health of a run: invariant drift and, for the adaptive method, its error control.

Usage (any stepping loop, e.g. ``Simulation``)::

    mon = HealthMonitor(energy=lambda y: ..., angular_momentum_W=lambda y: ...)
    mon.observe(y)                   # initial state
    for ...: integ.step(...); mon.observe(y)
    report = mon.report(integ)       # HealthReport

Invariants are only invariants for conservative scenes (no thrust, drag or torque); pass
``None`` for the ones that do not apply, and their drift is reported as ``None``.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.state import ATT, OMEGA_B


@dataclass(frozen=True)
class HealthReport:
    """Invariant drift of one run (maxima over all observed states).

    Attributes
    ----------
    samples : int
        Number of observed states.
    quat_norm_error : float | None
        ``max | |q| - 1 |`` (None in Euler-angle mode).
    energy_drift : float | None
        ``max |E - E0| / |E0|`` (relative; None when no energy function was given).
    momentum_drift : float | None
        ``max |L_W - L_W0| / |L_W0|``, world-frame angular momentum (relative).
    accepted, rejected : int | None
        Internal steps of the adaptive method (None for fixed-step methods).
    error_estimate : float | None
        The adaptive method's largest accepted normalised local error estimate (<= 1).
    global_error_bound : float | None
        In the adaptive method's ``error_control="global"`` mode: the largest bound of a call's
        accumulated error, in units of the tolerance (<= 1 when every call met it; None otherwise).
    """

    samples: int
    quat_norm_error: float | None
    energy_drift: float | None
    momentum_drift: float | None
    accepted: int | None = None
    rejected: int | None = None
    error_estimate: float | None = None
    global_error_bound: float | None = None

    def lines(self) -> list[str]:
        """Human-readable one-liners (for logs and bench output)."""
        def fmt(v: float | None) -> str:
            return "n/a" if v is None else f"{v:.3e}"
        out = [
            f"| |q|-1 | max     {fmt(self.quat_norm_error)}",
            f"energy drift rel  {fmt(self.energy_drift)}",
            f"|L_W| drift rel   {fmt(self.momentum_drift)}",
        ]
        if self.accepted is not None:
            out.append(f"adaptive steps    {self.accepted} accepted, {self.rejected} rejected, max error est {fmt(self.error_estimate)}")
        if self.global_error_bound is not None:
            out.append(f"global error      bound {fmt(self.global_error_bound)} x tolerance (max over calls)")
        return out


def _worst(current: float, new: float) -> float:
    """``max`` that lets a NaN (a run that blew up) show as ``inf`` instead of hiding it."""
    return max(current, new) if new == new else math.inf


def angular_momentum_W(y: np.ndarray, inertia_B: np.ndarray) -> np.ndarray:
    """World-frame angular momentum ``R(q)^T I omega_B`` [kg m^2/s] of a quaternion-mode state."""
    return rotation.body_to_world(y[ATT], np.asarray(inertia_B) * y[OMEGA_B])


class HealthMonitor:
    """Accumulates invariant drift over observed states (call :meth:`observe` after each step)."""

    def __init__(
        self,
        energy: Callable[[np.ndarray], float] | None = None,
        angular_momentum_W: Callable[[np.ndarray], np.ndarray] | None = None,
        quaternion: bool = True,
    ) -> None:
        self._energy = energy
        self._momentum = angular_momentum_W
        self._quaternion = quaternion
        self._n = 0
        self._e0 = 0.0
        self._L0: np.ndarray | None = None
        self._q_err = 0.0
        self._e_err = 0.0
        self._L_err = 0.0

    def observe(self, y: np.ndarray) -> None:
        """Record one state; the first call fixes the reference values ``E0``, ``L_W0``."""
        if self._quaternion:
            q = y[ATT]
            self._q_err = _worst(self._q_err, abs(math.sqrt(float(q @ q)) - 1.0))
        if self._energy is not None:
            e = float(self._energy(y))
            if self._n == 0:
                self._e0 = e
            else:
                self._e_err = _worst(self._e_err, abs(e - self._e0) / max(abs(self._e0), 1e-300))
        if self._momentum is not None:
            L = np.asarray(self._momentum(y), dtype=float)
            if self._L0 is None:
                self._L0 = L.copy()
            else:
                self._L_err = _worst(self._L_err, float(np.linalg.norm(L - self._L0)) / max(float(np.linalg.norm(self._L0)), 1e-300))
        self._n += 1

    def report(self, integrator: object | None = None) -> HealthReport:
        """The drift so far; adaptive counters are read from ``integrator`` if it has them."""
        accepted = getattr(integrator, "accepted", None)
        return HealthReport(
            samples=self._n,
            quat_norm_error=self._q_err if self._quaternion else None,
            energy_drift=self._e_err if self._energy is not None else None,
            momentum_drift=self._L_err if self._momentum is not None else None,
            accepted=accepted,
            rejected=getattr(integrator, "rejected", None) if accepted is not None else None,
            error_estimate=getattr(integrator, "max_error", None) if accepted is not None else None,
            global_error_bound=(getattr(integrator, "max_global_error", None)
                                if getattr(integrator, "error_control", None) == "global" else None),
        )
