"""Summary statistics: Wilson interval, percentiles, paired comparison."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_tools.sweep.summary import compare, metric_stats, summarise, wilson_interval


def test_wilson_interval_matches_its_closed_form():
    # 8 of 10 at 95 %: z = 1.959964; closed form (p + z^2/2n +- z sqrt(p q/n + z^2/4n^2)) / (1 + z^2/n).
    z, n, p = 1.959963984540054, 10, 0.8
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    iv = wilson_interval(8, 10)
    assert iv.estimate == 0.8
    assert iv.low == pytest.approx(c - h, rel=1e-12) and iv.high == pytest.approx(c + h, rel=1e-12)


def test_wilson_interval_at_all_successes_is_not_degenerate():
    # The Wald interval collapses to [1, 1]; Wilson gives the "rule of three"-like bound:
    # lower limit n / (n + z^2) exactly when p = 1.
    iv = wilson_interval(1000, 1000)
    z2 = 1.959963984540054**2
    assert iv.high == 1.0 and iv.low == pytest.approx(1000 / (1000 + z2), rel=1e-12)


def test_wilson_interval_rejects_impossible_counts():
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(5, 3)


def test_metric_stats_ignores_undefined_values():
    s = metric_stats([1.0, 2.0, math.nan, 3.0, None])
    assert s.count == 3 and s.percentiles["p50"] == 2.0 and s.max == 3.0


def _rows():
    rows = []
    for i in range(20):
        rows.append({"index": i, "controller": "a", "success": i % 4 != 0, "outcome": "ok" if i % 4 else "crashed", "fuel_used": float(i)})
        rows.append({"index": i, "controller": "b", "success": i % 5 != 0, "outcome": "ok" if i % 5 else "crashed", "fuel_used": float(i) + 1.5})
    return rows


def test_summary_counts_per_controller():
    a, b = summarise(_rows(), ["fuel_used"])
    assert (a.controller, a.flights, a.successes) == ("a", 20, 15)
    assert (b.controller, b.flights, b.successes) == ("b", 20, 16)
    assert a.outcomes == {"crashed": 5, "ok": 15}
    assert a.metrics["fuel_used"].percentiles["p50"] == pytest.approx(np.median(np.arange(20.0)))


def test_comparison_pairs_the_same_cases():
    c = compare(_rows(), "a", "b", ["fuel_used"])
    # a fails on multiples of 4, b on multiples of 5: both fail on 0; a alone on 4, 8, 12, 16; b alone on 5, 10, 15.
    assert (c.pairs, c.both_failed, c.only_b, c.only_a, c.both_succeeded) == (20, 1, 4, 3, 12)
    assert c.median_difference["fuel_used"] == pytest.approx(1.5)
