"""Summary statistics: Wilson interval, percentiles, paired comparison."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_tools.sweep.spec import Acceptance, Bound
from lander_tools.sweep.summary import compare, format_summary, metric_stats, summarise, wilson_interval


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


def test_acceptance_counts_every_flight_against_each_bound_and_names_the_ones_outside():
    rows = _rows()
    rows[2]["fuel_used"] = math.nan  # a's flight 1 (rows alternate a, b); a flight that never got there is outside any bound
    acc = Acceptance(success_rate=0.8, success_wilson_low=0.5, bounds=(Bound("fuel_used", max=17.0),))
    a, b = summarise(rows, ["fuel_used"], acceptance=acc)
    rate, wilson, fuel = a.acceptance
    # a: 15 of 20 succeed (75 % < 80 %); Wilson's lower bound for 15/20 is 53.1 % (>= 50 %)
    assert (rate.met, rate.measured) == (False, "75.0 %")
    assert wilson.met and wilson.measured == f"{100 * wilson_interval(15, 20).low:.1f} %"
    # a's fuel_used is the index: 18 and 19 are over 17, and flight 1 has none
    assert not fuel.met and fuel.measured == "17/20 flights"
    assert [i for i, _ in fuel.outside] == [1, 19, 18]  # undefined first, then the worst
    # b's is the index + 1.5: 16, 17, 18, 19 over (1 is NaN in a's row only)
    assert [i for i, _ in b.acceptance[2].outside] == [19, 18, 17, 16]
    text = format_summary([a, b])
    assert "acceptance: 1 of 3 met" in text
    assert "NOT MET fuel_used <= 17 kg, every flight: 17/20 flights (outside: #1 nan, #19 19, #18 18)" in text
    assert "met     Wilson lower bound >= 50 %" in text


def test_acceptance_met_when_every_flight_is_within():
    acc = Acceptance(bounds=(Bound("fuel_used", min=0.0, max=100.0),))
    (a, _b) = summarise(_rows(), ["fuel_used"], acceptance=acc)
    assert [c.met for c in a.acceptance] == [True] and a.acceptance[0].outside == ()
    assert summarise(_rows(), ["fuel_used"])[0].acceptance == ()  # none asked
