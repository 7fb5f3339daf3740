"""Turn per-flight rows into a summary: success rate with a Wilson interval, metric percentiles,
and a paired comparison of controllers flown on the same dispersed cases.

A row is a flat dict made by :func:`lander_tools.sweep.flight.fly_case`: ``index``,
``controller``, ``outcome``, ``success``, the case parameters and the metrics.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from lander_tools.sweep.spec import Acceptance, Bound, metric_label, metric_unit

#: Percentiles reported for each metric.
PERCENTILES = (5.0, 50.0, 95.0)


@dataclass(frozen=True)
class Interval:
    """A proportion with its confidence interval."""

    estimate: float
    low: float
    high: float
    confidence: float


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> Interval:
    """Wilson score interval for a binomial proportion.

    Unlike the normal (Wald) interval it stays inside [0, 1] and keeps close to nominal coverage
    at 0 or n successes, which is the usual case for a robust controller:
    ``(p + z^2/2n +- z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)``.
    """
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got successes={successes}, n={n}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if n == 0:
        return Interval(math.nan, 0.0, 1.0, confidence)
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + confidence / 2.0))
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # At 0 (or n) successes the closed form's lower (upper) limit is exactly 0 (1); say so rather
    # than leave a rounding residue of 1e-17.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return Interval(p, low, high, confidence)


@dataclass(frozen=True)
class MetricStats:
    """Distribution of one metric over the flights where it is defined (finite)."""

    count: int
    mean: float
    percentiles: dict[str, float]
    max: float


def metric_stats(values: Iterable[float | None]) -> MetricStats:
    a = np.asarray([v for v in values if v is not None], dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return MetricStats(0, math.nan, {f"p{p:g}": math.nan for p in PERCENTILES}, math.nan)
    pct = np.percentile(a, PERCENTILES)
    return MetricStats(int(a.size), float(a.mean()), {f"p{p:g}": float(v) for p, v in zip(PERCENTILES, pct)}, float(a.max()))


@dataclass(frozen=True)
class Check:
    """One line of a controller's acceptance: what was asked, what was measured, whether it is met;
    for a per-flight bound, the flights outside it (``(index, value)``, worst first)."""

    what: str
    measured: str
    met: bool
    outside: tuple[tuple[int, float], ...] = ()


@dataclass(frozen=True)
class ControllerSummary:
    controller: str
    flights: int
    successes: int
    success_rate: Interval
    outcomes: dict[str, int]
    metrics: dict[str, MetricStats]
    acceptance: tuple[Check, ...] = ()


#: Flights named per unmet bound (worst first); the rest are counted.
NAMED_OUTSIDE = 8


def _number(v: Any) -> float:
    """A row's metric value as a float; missing (None, "") is undefined (NaN)."""
    return math.nan if v is None or v == "" else float(v)


def _excess(b: Bound, v: float) -> float:
    """How far ``v`` is outside ``b`` (undefined: infinitely): flights outside a bound are listed worst first."""
    if not math.isfinite(v):
        return math.inf
    return max(v - b.max if b.max is not None else -math.inf, b.min - v if b.min is not None else -math.inf)


def check_acceptance(rows: Sequence[dict[str, Any]], acceptance: Acceptance, rate: Interval) -> tuple[Check, ...]:
    """The checks of ``acceptance`` on one controller's ``rows`` (``rate``: its success rate)."""
    checks = []
    if acceptance.success_rate is not None:
        checks.append(Check(f"success >= {100 * acceptance.success_rate:g} %", f"{100 * rate.estimate:.1f} %",
                            rate.estimate >= acceptance.success_rate))
    if acceptance.success_wilson_low is not None:
        checks.append(Check(f"Wilson lower bound >= {100 * acceptance.success_wilson_low:g} %", f"{100 * rate.low:.1f} %",
                            rate.low >= acceptance.success_wilson_low))
    for b in acceptance.bounds:
        values = [(int(r["index"]), _number(r.get(b.metric))) for r in rows]
        outside = sorted(((i, v) for i, v in values if not b.holds(v)), key=lambda iv: (-_excess(b, iv[1]), iv[0]))
        checks.append(Check(f"{b.describe()}, every flight", f"{len(values) - len(outside)}/{len(values)} flights",
                            not outside, tuple(outside)))
    return tuple(checks)


def summarise(rows: Sequence[dict[str, Any]], metrics: Sequence[str], confidence: float = 0.95,
              acceptance: Acceptance | None = None) -> list[ControllerSummary]:
    """One summary per controller label, in first-seen order; with ``acceptance``, its checks each."""
    labels = list(dict.fromkeys(r["controller"] for r in rows))
    out = []
    for label in labels:
        mine = [r for r in rows if r["controller"] == label]
        k = sum(bool(r["success"]) for r in mine)
        outcomes: dict[str, int] = {}
        for r in mine:
            outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
        rate = wilson_interval(k, len(mine), confidence)
        out.append(
            ControllerSummary(
                controller=label,
                flights=len(mine),
                successes=k,
                success_rate=rate,
                outcomes=dict(sorted(outcomes.items())),
                metrics={m: metric_stats(r.get(m) for r in mine) for m in metrics},
                acceptance=check_acceptance(mine, acceptance, rate) if acceptance is not None else (),
            )
        )
    return out


@dataclass(frozen=True)
class Comparison:
    """Controller ``b`` against baseline ``a`` on the cases both flew (paired by flight index).

    ``only_a`` counts cases ``a`` survived and ``b`` failed; ``median_difference`` is the median of
    ``b - a`` per metric over the pairs where both values are finite.
    """

    a: str
    b: str
    pairs: int
    both_succeeded: int
    only_a: int
    only_b: int
    both_failed: int
    median_difference: dict[str, float]


def compare(rows: Sequence[dict[str, Any]], a: str, b: str, metrics: Sequence[str]) -> Comparison:
    by_a = {r["index"]: r for r in rows if r["controller"] == a}
    by_b = {r["index"]: r for r in rows if r["controller"] == b}
    common = sorted(by_a.keys() & by_b.keys())
    counts = {"ss": 0, "sf": 0, "fs": 0, "ff": 0}
    for i in common:
        counts[("s" if by_a[i]["success"] else "f") + ("s" if by_b[i]["success"] else "f")] += 1
    med = {}
    for m in metrics:
        d = np.array([float(by_b[i][m]) - float(by_a[i][m]) for i in common], dtype=float)
        d = d[np.isfinite(d)]
        med[m] = float(np.median(d)) if d.size else math.nan
    return Comparison(a, b, len(common), counts["ss"], counts["sf"], counts["fs"], counts["ff"], med)


def to_jsonable(summaries: Sequence[ControllerSummary], comparisons: Sequence[Comparison] = ()) -> dict[str, Any]:
    return {"controllers": [asdict(s) for s in summaries], "comparisons": [asdict(c) for c in comparisons]}


def format_summary(summaries: Sequence[ControllerSummary], comparisons: Sequence[Comparison] = ()) -> str:
    """Human-readable summary, one block per controller and one per comparison."""
    lines: list[str] = []
    for s in summaries:
        r = s.success_rate
        lines.append(
            f"controller {s.controller}: {s.successes}/{s.flights} succeeded = {100 * r.estimate:.1f} % "
            f"({100 * r.confidence:.0f} % Wilson CI {100 * r.low:.1f}-{100 * r.high:.1f} %)"
        )
        lines.append("  outcomes: " + ", ".join(f"{k} {v}" for k, v in s.outcomes.items()))
        width = max([22] + [len(metric_label(n)) + 1 for n in s.metrics])
        head = "  {:<" + str(width) + "}{:>7}" + "{:>12}" * (len(PERCENTILES) + 1)
        lines.append(head.format("metric [unit]", "n", *[f"p{p:g}" for p in PERCENTILES], "max"))
        for name, m in s.metrics.items():
            vals = [m.percentiles[f"p{p:g}"] for p in PERCENTILES] + [m.max]
            lines.append(head.format(metric_label(name), m.count, *[f"{v:.4g}" for v in vals]))
        ct = s.metrics.get("compute_time")
        if ct is not None and ct.count:
            lines.append(f"  compute: {ct.mean * ct.count:.3g} s of CPU in the controller's updates over {ct.count} "
                         f"flights = {ct.mean:.3g} s a flight (mean; median {ct.percentiles['p50']:.3g} s)")
        if s.acceptance:
            met = sum(c.met for c in s.acceptance)
            lines.append(f"  acceptance: {met} of {len(s.acceptance)} met")
            for c in s.acceptance:
                line = f"    {'met    ' if c.met else 'NOT MET'} {c.what}: {c.measured}"
                if c.outside:
                    named = ", ".join(f"#{i} {v:.4g}" for i, v in c.outside[:NAMED_OUTSIDE])
                    more = len(c.outside) - NAMED_OUTSIDE
                    line += f" (outside: {named}" + (f" and {more} more" if more > 0 else "") + ")"
                lines.append(line)
    for cmp in comparisons:
        lines.append(
            f"compare {cmp.b} vs {cmp.a} on {cmp.pairs} shared cases: both ok {cmp.both_succeeded}, "
            f"only {cmp.a} ok {cmp.only_a}, only {cmp.b} ok {cmp.only_b}, both failed {cmp.both_failed}"
        )
        lines.append("  median difference (" + cmp.b + " - " + cmp.a + "): "
                     + ", ".join(f"{k} {v:.4g} {metric_unit(k)}" for k, v in cmp.median_difference.items()))
    return "\n".join(lines)
