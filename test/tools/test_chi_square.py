"""The time-averaged chi-square record (lander_tools.chi_square) that the estimate's analysis reports
for NEES and NIS alike: its intervals are the chi-square quantiles the theory gives, its counts are
the values', and a block's NEES and a sensor's NIS of the same values are the same record."""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from lander_tools.chi_square import ChiSquareSummary
from lander_tools.estimate_analysis import nees_check
from lander_tools.estimate_nis import SensorNis

DOF, N = 3, 400


def _values() -> np.ndarray:
    return np.random.default_rng(7).chisquare(DOF, N)


def test_the_intervals_are_the_chi_square_quantiles_and_the_counts_the_values() -> None:
    v = _values()
    s = ChiSquareSummary.of(v, DOF)
    assert (s.dof, s.samples) == (DOF, N)
    assert s.mean == float(np.mean(v))
    # N times the average of N independent chi-square(n) values is chi-square(n N).
    np.testing.assert_allclose(s.bounds, chi2.ppf([0.025, 0.975], DOF * N) / N, rtol=1e-12)
    np.testing.assert_allclose(s.bounds_one, chi2.ppf([0.025, 0.975], DOF), rtol=1e-12)
    lo, hi = s.bounds_one
    assert s.frac_inside == np.count_nonzero((v >= lo) & (v <= hi)) / N
    assert s.inside == (s.bounds[0] <= s.mean <= s.bounds[1])
    assert s.inside_one == (lo <= s.mean <= hi)
    # The mean of N chi-square(n) values: n within 5 of its standard deviations, sqrt(2 n / N); four
    # times the values (a covariance 4 times too small) leave the independent-values interval.
    assert abs(s.mean - DOF) < 5.0 * np.sqrt(2.0 * DOF / N)
    assert not ChiSquareSummary.of(4.0 * v, DOF).inside


def test_nees_and_nis_of_the_same_values_are_one_record() -> None:
    v = _values()
    nees = nees_check(np.append(v, np.nan), DOF)  # a singular P's NaN is left out
    nis = SensorNis.of(v, DOF, 0.95, sensor="doppler", t=np.arange(N) * 0.1, values=v)
    base = ChiSquareSummary.of(v, DOF)
    assert nees == base
    assert (nis.mean, nis.dof, nis.samples, nis.bounds, nis.bounds_one, nis.frac_inside) == (
        base.mean, base.dof, base.samples, base.bounds, base.bounds_one, base.frac_inside)
    assert nis.cells() == base.cells()
