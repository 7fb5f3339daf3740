"""Gain scheduling: a linear law redesigned over the descent and interpolated at run time.

Over a de-orbit descent the vertical dynamics change by orders of magnitude: the mass falls as fuel
burns (the input gain ``T_v / m`` rises) and the drag's damping ``rho Cd A |v| / m`` goes from zero
in vacuum to dominating at the bottom of the atmosphere. A fixed gain designed at one condition
places the closed-loop poles elsewhere at every other. Here the vertical model is linearised about
steady descents on a grid of scheduling variables ``mu = (mass [kg], dynamic-pressure parameter)``,
the gain is placed at every grid point, and the law interpolates the gain at run time.

Vertical model about a steady descent at speed ``v0 > 0`` (down), altitude ``h``, mass ``m``
(control reference eq 9-16, with the drag of the dynamics reference's sphere model added)::

    x = [h - h_ref, h' - h'_ref],   u = throttle - u_ref
    A = [[0, 1], [0, -d]],   d = rho(h) Cd A v0 / m   (d(drag accel)/dh' at h' = -v0)
    B = [[0], [T_v / m]]

The scheduling variable for the drag is ``d`` itself (1/s): it folds density, speed and mass into
the one number the linear model depends on. Interpolation is piecewise linear on the Delaunay
triangulation of the grid and the nearest grid point's gain outside it: the same rule as
python-control's gain-scheduled state feedback (``create_statefbk_iosystem`` with
``gainsched_method='linear'``, scipy's ``griddata``), which :func:`to_iosystem` builds from the same
schedule so the two can be held to each other.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import DesignError
from .gains import place_poles


@dataclass(frozen=True)
class GainSchedule:
    """Gains ``K_j`` (m x n) designed at scheduling points ``mu_j`` (d values each).

    ``labels`` name the scheduling variables (with units), ``poles`` the poles every ``K_j`` places.
    """

    points: np.ndarray  # (p, d)
    gains: np.ndarray  # (p, m, n)
    labels: tuple[str, ...]
    poles: tuple[complex, ...]

    def __post_init__(self) -> None:
        from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

        pts = np.asarray(self.points, float)
        K = np.asarray(self.gains, float)
        if pts.ndim != 2 or K.ndim != 3 or len(pts) != len(K) or pts.shape[1] != len(self.labels):
            raise DesignError(f"schedule: {len(pts)} points of {pts.shape[1:]} and gains of {K.shape} do not match")
        flat = K.reshape(len(K), -1)
        object.__setattr__(self, "_linear", LinearNDInterpolator(pts, flat))
        object.__setattr__(self, "_nearest", NearestNDInterpolator(pts, flat))

    def gain(self, mu: Any) -> np.ndarray:
        """``K(mu)``: linear on the triangulation, the nearest point's gain outside its hull."""
        mu = np.asarray(mu, float).reshape(1, -1)
        k = self._linear(mu)[0]  # type: ignore[attr-defined]  # set in __post_init__ (frozen dataclass)
        if not np.all(np.isfinite(k)):
            k = self._nearest(mu)[0]  # type: ignore[attr-defined]  # set in __post_init__ (frozen dataclass)
        return np.asarray(k).reshape(self.gains.shape[1:])


def vertical_descent_model(mass: float, damping: float, thrust_vertical: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the vertical motion about a steady descent (module docstring)."""
    if not (mass > 0 and thrust_vertical > 0 and damping >= 0):
        raise DesignError(f"need mass > 0, thrust > 0 and damping >= 0; got {mass}, {thrust_vertical}, {damping}")
    return np.array([[0.0, 1.0], [0.0, -damping]]), np.array([[0.0], [thrust_vertical / mass]])


def _schedule_grid(model: Callable[[float, float, float], tuple[np.ndarray, np.ndarray]], thrust_vertical: float, masses: Any, dampings: Any,
                   poles: tuple[complex, ...]) -> GainSchedule:
    """The gain of ``model(mass, damping, thrust_vertical) -> (A, B)`` placing ``poles`` at every
    ``(mass [kg], damping [1/s])`` of the grid."""
    ms, ds = np.asarray(masses, float).ravel(), np.asarray(dampings, float).ravel()
    if len(ms) < 2 or len(ds) < 2:
        raise DesignError("schedule: need at least two masses and two dampings (a grid to interpolate on)")
    points, gains = [], []
    for m in ms:
        for d in ds:
            A, B = model(m, d, thrust_vertical)
            points.append((m, d))
            gains.append(place_poles(A, B, list(poles)).K)
    return GainSchedule(np.array(points), np.array(gains), ("mass [kg]", "drag damping [1/s]"), tuple(poles))


def schedule_vertical(thrust_vertical: float, masses: Any, dampings: Any,
                      poles: tuple[complex, ...] = (-0.9, -1.1)) -> GainSchedule:
    """The vertical law's gain placed at every ``(mass [kg], damping [1/s])`` of the grid."""
    return _schedule_grid(vertical_descent_model, thrust_vertical, masses, dampings, poles)


def descent_rate_model(mass: float, damping: float, thrust_vertical: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the descent-rate error about a steady descent: ``A = [[-d]]``, ``B = [[T_v / m]]``.

    The velocity loop of the de-orbit law's braking curve (:class:`..controllers.deorbit.DescentToAltitude`)
    tracks a descent rate given as a function of altitude; its error obeys the second row of
    :func:`vertical_descent_model` alone.
    """
    A, B = vertical_descent_model(mass, damping, thrust_vertical)
    return A[1:, 1:], B[1:]


def schedule_descent_rate(thrust_vertical: float, masses: Any, dampings: Any, pole: float = -2.0) -> GainSchedule:
    """The descent-rate gain [throttle per m/s] placing ``pole`` at every ``(mass, damping)`` of the grid.

    Closed loop ``-d - (T_v / m) K = pole``: ``K = (-pole - d) m / T_v``. Where the air already
    damps (``d`` large, under the chute near the ground) the gain asks less; as the mass falls the
    same throttle gives more acceleration, so the gain falls with it. Linear in ``m`` and ``d``
    separately but not jointly, so the interpolated gain differs from the exact one by a second-order
    term in the grid step (``test_schedule.py`` measures it).
    """
    if not pole < 0:
        raise DesignError(f"schedule: the descent-rate pole must be negative (stable), got {pole}")
    return _schedule_grid(descent_rate_model, thrust_vertical, masses, dampings, (pole,))


def to_iosystem(schedule: GainSchedule, n_states: int) -> Any:
    """python-control's gain-scheduled state feedback of the same schedule.

    The plant given to ``create_statefbk_iosystem`` has the law's ``n_states`` states followed by
    one constant state per scheduling variable (zero dynamics, zero gain columns), so the
    scheduling variables can be named among the controller's inputs ``[x_d, u_d, x]``: the
    controller's output is ``u_d - K(mu) (x - x_d)`` with ``mu`` read from ``x``.
    """
    import control

    d = schedule.points.shape[1]
    m = schedule.gains.shape[1]
    n = n_states + d
    plant = control.ss(np.zeros((n, n)), np.zeros((n, m)), np.eye(n), np.zeros((n, m)))
    gains = [np.hstack([K, np.zeros((m, d))]) for K in schedule.gains]
    # [x_d (n), u_d (m), x (n)]: the scheduling variables are the last d entries of x
    idx = [n + m + n_states + i for i in range(d)]
    ctrl, _ = control.create_statefbk_iosystem(plant, (gains, list(map(tuple, schedule.points))),
                                               gainsched_indices=idx, gainsched_method="linear")
    return ctrl
