"""A bag's span (lander_tools.bagspan) and `lander analyse` printing it: a bag that does not start at
t = 0, has a gap in the state sequence or holds two flights is flagged."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from lander_tools.bagspan import bag_span

from .synth import write_flight_bag

REPO = Path(__file__).resolve().parents[2]


def test_a_whole_flight_has_no_problem() -> None:
    span = bag_span(np.arange(11) * 0.1, np.arange(1, 12))
    assert span.problems() == [] and span.states == 11 and span.t_last == 1.0
    assert "whole" in span.describe()


def test_a_late_start_a_gap_and_a_restart_are_each_named() -> None:
    late = bag_span(np.array([2.0, 2.1, 2.2]), np.array([21, 22, 23]))
    assert late.problems() == ["does not start at t = 0 (first state 21 at t = 2.000 s)"]
    gap = bag_span(np.array([0.0, 0.1, 0.4, 0.5]), np.array([1, 2, 5, 6]))
    assert gap.gaps == [(2, 5)] and gap.missing == 2 and "2 states missing in 1 gaps (2->5)" in gap.problems()[0]
    two = bag_span(np.array([0.0, 0.1, 0.0, 0.1]), np.array([1, 2, 1, 2]))
    assert two.restarts == 1 and two.gaps == [] and "restarts 1 times" in two.problems()[0]
    assert bag_span(np.zeros(0), np.zeros(0)).problems() == ["no state in the bag"]


def _analyse(*bags: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", "analyse", *map(str, bags), "--json"],
                          check=False, capture_output=True, text=True, cwd=REPO, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(REPO)))


def test_lander_analyse_prints_each_bags_span_and_flags_a_late_start(tmp_path: Path) -> None:
    t = np.arange(0.0, 5.0, 0.1)
    write_flight_bag(tmp_path / "whole", t, np.full_like(t, 500.0), np.zeros_like(t))
    write_flight_bag(tmp_path / "late", t + 2.0, np.full_like(t, 500.0), np.zeros_like(t))
    res = _analyse(tmp_path / "whole", tmp_path / "late")
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    whole = next(x for x in lines if "/whole:" in x)
    late = next(x for x in lines if "/late:" in x)
    assert "t = 0.000 to 4.900 s, 50 states" in whole and "warning" not in whole, lines
    assert late.startswith("lander analyse: warning: ") and "does not start at t = 0" in late, lines
