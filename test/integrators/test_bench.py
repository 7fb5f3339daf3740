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
