"""Filter consistency: NEES and NIS and their chi-square bounds (Bar-Shalom, Li and Kirubarajan,
*Estimation with Applications to Tracking and Navigation*, 2001, section 5.4).

* **NEES** ``e^T P^-1 e`` of the estimation error ``e`` (truth minus estimate, in the filter's
  error-state coordinates): for a consistent filter it is chi-square with ``n`` (the error
  state's dimension) degrees of freedom at every time.
* **NIS** ``y^T S^-1 y`` of an innovation ``y`` with its predicted covariance ``S``: chi-square with
  ``dim y`` degrees of freedom, and the innovations of a consistent filter are white, so NIS values
  at different times are independent.

**Monte Carlo test** over ``M`` runs: the average NEES over the runs at one time, ``M`` times it,
is chi-square with ``M n`` degrees of freedom, so its two-sided 95 % interval is
``[chi2(0.025; M n) / M, chi2(0.975; M n) / M]`` (:func:`average_bounds`); ``n`` is inside it when the
filter's covariance matches its errors. The time-average of that run-average (ANEES, over ``K``
times) is tested against the same single-time interval: averaging correlated errors over time
narrows its spread, so the single-time interval holds it with room. The NIS of all updates of
one sensor (``N`` values of ``p`` components each, independent) sum to a chi-square of ``N p``
degrees of freedom: the interval of their average is exact (:func:`average_bounds` with
``runs = N``, ``dof = p``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .ekf import DBA, DBG, DR, DTH, DV, N_ERR, NavState, attitude_error


def error_state(state: NavState, r_W: np.ndarray, v_W: np.ndarray, q: np.ndarray, b_g: np.ndarray,
                b_a: np.ndarray) -> np.ndarray:
    """``e`` (15): truth minus estimate, with the attitude error ``th`` of ``q = q_est x dq(th)``."""
    e = np.zeros(N_ERR)
    e[DR] = r_W - state.r_W
    e[DV] = v_W - state.v_W
    e[DTH] = attitude_error(state.q, q)
    e[DBG] = b_g - state.b_g
    e[DBA] = b_a - state.b_a
    return e


def nees(e: np.ndarray, P: np.ndarray) -> float:
    """``e^T P^-1 e``."""
    return float(e @ np.linalg.solve(P, e))


def average_bounds(dof: int, runs: int, prob: float = 0.95) -> tuple[float, float]:
    """Two-sided ``prob`` interval of the average of ``runs`` independent chi-square(``dof``) values."""
    from scipy.stats import chi2

    a = 0.5 * (1.0 - prob)
    return float(chi2.ppf(a, dof * runs) / runs), float(chi2.ppf(1.0 - a, dof * runs) / runs)


@dataclass(frozen=True)
class ConsistencyCheck:
    """``value`` (an average NEES or NIS), its ``dof`` and ``bounds``; ``inside`` when it lies within."""

    value: float
    dof: int
    bounds: tuple[float, float]

    @property
    def inside(self) -> bool:
        return self.bounds[0] <= self.value <= self.bounds[1]


def anees(nees_runs: np.ndarray, dof: int, prob: float = 0.95) -> tuple[ConsistencyCheck, float]:
    """ANEES of an ``(M runs, K times)`` array and the fraction of times whose run-average lies
    inside the single-time interval (module docstring)."""
    a = np.asarray(nees_runs, float)
    M = a.shape[0]
    lo, hi = average_bounds(dof, M, prob)
    per_time = a.mean(axis=0)
    frac = float(np.mean((per_time >= lo) & (per_time <= hi)))
    return ConsistencyCheck(float(per_time.mean()), dof, (lo, hi)), frac


def anis(nis_values: np.ndarray, dof: int, prob: float = 0.95) -> ConsistencyCheck:
    """Average NIS of independent values of ``dof`` components each, with its exact interval."""
    v = np.asarray(nis_values, float).ravel()
    return ConsistencyCheck(float(v.mean()), dof, average_bounds(dof, v.size, prob))
