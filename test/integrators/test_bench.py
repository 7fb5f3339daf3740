"""The benchmarks run and report sane figures (quick mode); `lander bench` rejects unknown names."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from lander_tools.commands import bench

BENCH = Path(__file__).resolve().parents[2] / "bench"


def test_unknown_benchmark_lists_the_choices() -> None:
    with pytest.raises(ValueError, match="unknown benchmark 'fastest'; choose one of: integrators, extremes, models, speed"):
        bench.run(argparse.Namespace(name="fastest", json=None, out=None, quick=True))


def test_models_benchmark_quick_writes_positive_rates(tmp_path: Path) -> None:
    # Behaviour, not timings (the machine is shared and noisy): every scene and every model
    # stage must report a finite positive rate.
    out = tmp_path / "models.json"
    assert bench.run(argparse.Namespace(name="models", json=str(out), out=None, quick=True)) == 0
    data = json.loads(out.read_text())
    assert data["scenes"] and all(r["steps_per_s"] > 0 for r in data["scenes"])
    assert len(data["one_by_one"]) == 6 and all(r["steps_per_s"] > 0 for r in data["one_by_one"])


@pytest.mark.slow
def test_closed_loop_benchmark_quick_writes_both_loop_and_sweep_rates(tmp_path: Path) -> None:
    # Behaviour, not timings: every rate is measured in the run and positive, the two loops fly
    # the same trajectory (the 1e-9 of test/control/test_compiled_loop.py) and the two sweep paths
    # print the same summary.
    out = tmp_path / "closed_loop.json"
    assert bench.run(argparse.Namespace(name="closed_loop", json=str(out), out=None, quick=True)) == 0
    data = json.loads(out.read_text())
    for key in ("python_loops_per_s", "compiled_loops_per_s", "per_flight_flights_per_s", "batched_flights_per_s",
                "estimate_batched_loops_per_s", "estimate_per_flight_flights_per_s", "estimate_batched_flights_per_s"):
        assert data[key] > 0, key
    assert max(data["trajectory_rel_diff"].values()) <= 1e-9
    assert data["summary_equal"]
    # on the estimate too: the batched path (sensors and filter in the loop) and the per-flight one agree
    assert data["estimate_batched_path"] == "batched (sensors and navigation filter compiled in the loop)"
    assert data["estimate_summary_equal"]
