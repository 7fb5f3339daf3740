"""The time average of a chi-square statistic against its bounds: the one record the estimate's
analysis reports for the NEES of a state block (:mod:`lander_tools.estimate_analysis`) and the NIS
of a sensor (:mod:`lander_tools.estimate_nis`). Plain numpy, no rclpy.

For a consistent filter each of ``N`` values ``eps_k`` of a statistic with ``n`` degrees of freedom
(NEES ``e^T P^-1 e``, NIS ``y^T S^-1 y``) is chi-square(``n``). The record holds:

* the time average ``mean = (1/N) sum eps_k``;
* ``bounds``, its exact two-sided interval of probability ``prob`` were the ``N`` values
  independent: ``N mean ~ chi-square(n N)``, so ``[chi2(a; n N), chi2(1 - a; n N)] / N`` with
  ``a = (1 - prob) / 2``; ``inside`` says the mean lies in it;
* ``bounds_one``, the single-value interval ``[chi2(a; n), chi2(1 - a; n)]``, and ``frac_inside``,
  the fraction of the values in it (``prob`` for a consistent filter); ``inside_one`` says the
  mean lies in it (the check that holds for correlated values, as a flight's NEES are).

Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001,
section 5.4; the intervals are :func:`lander_autopilot.estimation.consistency.average_bounds`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from lander_autopilot.estimation.consistency import anis, average_bounds


@dataclass(frozen=True)
class ChiSquareSummary:
    """A time-averaged chi-square statistic (module docstring): ``mean`` of ``samples`` values of
    ``dof`` degrees of freedom, the interval for that many independent values (``bounds``), the
    single-value interval (``bounds_one``) and the fraction of the values inside it."""

    mean: float
    dof: int
    samples: int
    bounds: tuple[float, float]
    bounds_one: tuple[float, float]
    frac_inside: float

    @classmethod
    def of(cls, values: Any, dof: int, prob: float = 0.95, /, **extra: Any) -> Self:
        """The summary of ``values`` (each of ``dof`` degrees of freedom) at probability ``prob``;
        ``extra``: the fields a subclass adds."""
        v = np.asarray(values, float).ravel()
        average = anis(v, dof, prob)  # the mean and its interval for independent values
        lo, hi = average_bounds(dof, 1, prob)
        return cls(mean=average.value, dof=dof, samples=int(v.size), bounds=average.bounds, bounds_one=(lo, hi),
                   frac_inside=float(np.mean((v >= lo) & (v <= hi))), **extra)

    @property
    def inside(self) -> bool:
        """The mean lies in the interval for independent values."""
        return self.bounds[0] <= self.mean <= self.bounds[1]

    @property
    def inside_one(self) -> bool:
        """The mean lies in the single-value interval."""
        return self.bounds_one[0] <= self.mean <= self.bounds_one[1]

    def cells(self) -> list[str]:
        """The mean, the two intervals and the fraction inside, as the terminal's tables print them."""
        return [f"{self.mean:.4g}", f"[{self.bounds[0]:.4g}, {self.bounds[1]:.4g}]",
                f"[{self.bounds_one[0]:.4g}, {self.bounds_one[1]:.4g}]", f"{self.frac_inside:.4f}"]
