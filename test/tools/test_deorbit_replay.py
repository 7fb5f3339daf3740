"""bench/deorbit_replay.py: a case replayed from its snapshot under the chute is the sweep's flight,
bit for bit (the tool's own --check, on one 200 km case), and it says when a snapshot is missing."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "sweeps" / "deorbit-200km.yaml"


def _tool():
    spec = importlib.util.spec_from_file_location("deorbit_replay", ROOT / "bench" / "deorbit_replay.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses and the worker pool look the module up by name
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow  # three ~2000 s flights core-only, ~25 s
def test_replay_from_the_snapshot_is_the_sweeps_flight(tmp_path, capsys):
    tool = _tool()
    folder = str(tmp_path / "snapshots")
    args = [str(SPEC), "--controller", "scheduled", "--folder", folder, "--cases", "7", "--workers", "1"]
    assert tool.main(["make", *args]) == 0
    assert (tmp_path / "snapshots" / "7.pkl").exists()
    made = capsys.readouterr().out
    # replay, then --check flies case 7 whole with the sweep's fly_case: exit 0 only if the fuel_ratio is the same
    assert tool.main(["replay", *args, "--check", "1"]) == 0
    out = capsys.readouterr().out
    assert "check case 7:" in out and ": same" in out
    # the replay's summary line equals the make run's (the same flight from the same instant)
    line = next(x for x in made.splitlines() if x.startswith("fuel_ratio"))
    assert line in out


def test_a_case_without_its_snapshot_is_reported_not_flown(tmp_path, capsys):
    tool = _tool()
    code = tool.main(["replay", str(SPEC), "--folder", str(tmp_path), "--cases", "3", "--workers", "1"])
    assert code == 0
    assert "1 flights: 1 no snapshot" in capsys.readouterr().out


def test_a_snapshot_from_older_code_gets_the_current_design_and_keeps_its_state():
    # A controller pickled before a change of the hover's attitude poles and of the braking's margins
    # (and without an attribute the current reset() adds): replayed, it flies the current gains and
    # margins, and what it learnt stays.
    import numpy as np

    from lander_autopilot.controllers import make_controller
    from lander_sim.scenes import load_scene

    tool = _tool()
    vehicle = load_scene("deorbit-200km").vehicle
    old = make_controller("deorbit", vehicle, hover_attitude_poles=[-2.0] * 6, brake_fraction=0.95)
    fresh = make_controller("deorbit", vehicle)
    old.descent.drag_scale = 0.87  # learnt under the chute
    del old.descent.law.heading_W
    del old.descent.stop_above  # an older pickle's descent has no instance attribute of it
    assert not np.array_equal(old.hover.law.attitude.K, fresh.hover.law.attitude.K)
    tool._fill_missing(old, fresh)
    assert np.array_equal(old.hover.law.attitude.K, fresh.hover.law.attitude.K)
    assert old.descent.drag_scale == 0.87 and old.descent.law.heading_W is fresh.descent.law.heading_W
    # the braking's margins too: the replay flies the current code's
    assert (old.descent.law.brake_fraction, old.descent.stop_above) == (fresh.descent.law.brake_fraction, fresh.descent.stop_above)


def test_a_frozen_record_from_older_code_gets_the_fields_added_since():
    # A settings record (frozen dataclass) pickled before a field was added: the field is given,
    # its other values kept (setattr on a frozen record would raise).
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Settings:
        a: float = 1.0
        b: float = 2.0

    tool = _tool()
    old, fresh = Settings(a=5.0), Settings()
    object.__delattr__(old, "b")  # as unpickled from a version without b
    tool._fill_missing(old, fresh)
    assert vars(old) == {"a": 5.0, "b": 2.0}
