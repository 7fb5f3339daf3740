"""bench/guard.py's table: medians per tree, the ratio of the medians, the run-by-run ratio range and
the within-tree ratios, from fake timings (the timings themselves are the machine's, not tested)."""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from pathlib import Path

import pytest

from lander_tools.commands import bench

BENCH = Path(__file__).resolve().parents[2] / "bench"


def _guard():
    if str(BENCH) not in sys.path:
        sys.path.insert(0, str(BENCH))  # the benchmarks import their _common as a top-level module
    spec = importlib.util.spec_from_file_location("lander_bench_guard", BENCH / "guard.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up here
    spec.loader.exec_module(module)
    return module


def test_medians_ratio_and_run_by_run_range() -> None:
    g = _guard()
    figs = [g.Figure("kernel", "kernel", "steps/s"), g.Figure("ceiling", "ceiling", "steps/s")]
    a = {"kernel": [2.0, 4.0, 3.0], "ceiling": [4.0, 8.0, 6.0]}
    b = {"kernel": [1.0, 1.0, 3.0], "ceiling": [4.0, 8.0, 6.0]}
    rows = {r.label: r for r in g.summarise(a, b, figs, [("kernel/ceiling", "kernel", "ceiling")])}
    k = rows["kernel"]
    assert (k.median_a, k.median_b, k.ratio) == (3.0, 1.0, 3.0)  # ratio of the medians, not median of ratios
    assert (k.ratio_low, k.ratio_high) == (1.0, 4.0)  # runs paired by index: 2/1, 4/1, 3/3
    c = rows["ceiling"]
    assert (c.ratio, c.ratio_low, c.ratio_high) == (1.0, 1.0, 1.0)
    d = rows["kernel/ceiling"]  # per run within one tree: A 0.5, 0.5, 0.5; B 0.25, 0.125, 0.5
    assert (d.median_a, d.median_b, d.ratio) == (0.5, 0.25, 2.0)


def test_a_figure_one_tree_cannot_measure_has_no_ratio_and_prints_a_dash() -> None:
    g = _guard()
    figs = [g.Figure("closed_loop", "closed loop", "loops/s")]
    nan = math.nan
    rows = g.summarise({"closed_loop": [5.0, 7.0, 6.0]}, {"closed_loop": [nan, nan, nan]}, figs, [])
    (r,) = rows
    assert r.median_a == 6.0 and math.isnan(r.median_b) and math.isnan(r.ratio) and math.isnan(r.ratio_low)
    line = g.format_table(rows, "A", "B", 3).splitlines()[-1]
    assert line.split()[-3:] == ["-", "-", "-"] and "6" in line


def test_a_missing_run_is_left_out_of_the_median() -> None:
    g = _guard()
    figs = [g.Figure("kernel", "kernel", "steps/s")]
    (r,) = g.summarise({"kernel": [1.0, math.nan, 3.0]}, {"kernel": [1.0, 2.0, 3.0]}, figs, [])
    assert (r.median_a, r.median_b, r.ratio_low, r.ratio_high) == (2.0, 2.0, 1.0, 1.0)


def test_guard_options_belong_to_the_guard_only() -> None:
    with pytest.raises(ValueError, match="--against: options of the guard benchmark only"):
        bench.run(argparse.Namespace(name="speed", json=None, out=None, quick=True, against="HEAD", runs=None, figures=None))
