"""`lander sweep`: bad specs name the key; a tiny sweep writes its table, summary and plots;
`--replay` reprints the sweep's row for that flight."""
from __future__ import annotations

import csv
import json

import yaml

from lander_tools.cli import main

from .conftest import SMALL


def _write(tmp_path, data, name="spec.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return str(p)


def test_bad_spec_exits_2_naming_the_key(tmp_path, capsys):
    cases = {
        "flights": ({**SMALL, "flights": -3}, "flights: must be >= 1, got -3"),
        "unknown": ({**SMALL, "wind": 3}, "wind: unknown key"),
        "std": ({**SMALL, "dispersions": {"wind_mean": {"normal": {"mean": 0, "std": -1}}}},
                "dispersions.wind_mean.normal.std"),
        "minmax": ({**SMALL, "dispersions": {"initial_altitude": {"uniform": {"min": 3, "max": 1}}}},
                   "dispersions.initial_altitude.uniform.min"),
        "controller": ({**SMALL, "controllers": ["no-such-law"]}, "unknown controller 'no-such-law'"),
    }
    for name, (data, needle) in cases.items():
        assert main(["sweep", _write(tmp_path, data, f"{name}.yaml")]) == 2, name
        err = capsys.readouterr().err
        assert needle in err and f"{name}.yaml" in err or name == "controller", err


def test_flights_override_is_checked(tmp_path, capsys):
    assert main(["sweep", _write(tmp_path, SMALL), "--flights", "0"]) == 2
    assert "--flights: must be >= 1" in capsys.readouterr().err


def test_tiny_sweep_writes_table_summary_and_plots_and_replay_matches(tmp_path, capsys):
    spec = _write(tmp_path, {**SMALL, "flights": 3, "end": {"duration": 4.0, "demand_step_time": 1.0, "hover_window": 1.0}})
    out = tmp_path / "out"
    assert main(["sweep", spec, "--workers", "1", "--out", str(out), "--progress", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    s = printed["controllers"][0]
    assert s["flights"] == 3 and 0.0 <= s["success_rate"]["low"] <= s["success_rate"]["estimate"] <= s["success_rate"]["high"] <= 1.0
    with open(out / "flights.csv") as f:
        table = list(csv.DictReader(f))
    assert [int(r["index"]) for r in table] == [0, 1, 2]
    assert json.loads((out / "summary.json").read_text())["flights"] == 3
    for png in ("histograms.png", "scatter.png", "worst.png"):
        assert (out / "plots" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    assert main(["sweep", spec, "--replay", "2", "--json"]) == 0
    replay = json.loads(capsys.readouterr().out)[0]
    # CSV floats are written with repr, so the replayed flight must print the very same numbers.
    for key in ("hover_error", "fuel_used", "max_tilt", "tilt", "wind_gust"):
        assert repr(replay[key]) == table[2][key], key


def test_through_ros_count_is_checked(tmp_path, capsys):
    spec = _write(tmp_path, {**SMALL, "flights": 2})
    assert main(["sweep", spec, "--through-ros", "0"]) == 2
    assert "--through-ros: must be >= 1" in capsys.readouterr().err
    assert main(["sweep", spec, "--through-ros", "3"]) == 2
    assert "more than the sweep's 2 flights" in capsys.readouterr().err


def test_sweep_without_out_writes_into_a_git_ignored_folder_of_the_working_directory(tmp_path, monkeypatch, capsys):
    # A sweep run from the checkout without --out must leave nothing that git would offer to commit.
    import subprocess
    from pathlib import Path

    from lander_tools.commands.sweep import DEFAULT_OUT

    spec = _write(tmp_path, {**SMALL, "flights": 2, "end": {"duration": 2.0, "demand_step_time": 1.0, "hover_window": 1.0}})
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["sweep", spec, "--workers", "1", "--no-plots", "--no-progress"]) == 0
    capsys.readouterr()
    written = work / DEFAULT_OUT / SMALL["name"]
    assert (written / "summary.json").is_file()
    assert sorted(p.name for p in work.iterdir()) == [DEFAULT_OUT.split("/")[0]]
    # The same relative path inside the checkout is ignored by git (its .gitignore covers it).
    repo = Path(__file__).resolve().parents[2]
    probe = f"{DEFAULT_OUT}/{SMALL['name']}/summary.json"
    ignored = subprocess.run(["git", "check-ignore", "-q", probe], cwd=repo, check=False)
    assert ignored.returncode == 0, f"{probe} is not git-ignored in {repo}"


def test_acceptance_is_checked_against_the_flown_rows_and_printed(tmp_path, capsys):
    """The spec's acceptance, checked on what the sweep flew: a bound at the second least fuel of a
    first run of the same flights, so the flights over it are those that run's table shows over it."""
    small = {**SMALL, "flights": 4, "metrics": ["fuel_used", "hover_error"],
             "end": {"duration": 4.0, "demand_step_time": 1.0, "hover_window": 1.0}}
    out = tmp_path / "first"
    assert main(["sweep", _write(tmp_path, small, "first.yaml"), "--workers", "1", "--out", str(out), "--no-plots"]) == 0
    capsys.readouterr()
    with open(out / "flights.csv") as f:
        fuel = {int(r["index"]): float(r["fuel_used"]) for r in csv.DictReader(f)}
    cut = sorted(fuel.values())[1]  # the second least: at least two flights within it
    over = sorted((i for i, v in fuel.items() if v > cut), key=lambda i: -fuel[i])
    assert over, "the four flights burn the same fuel: no bound between them"
    spec = _write(tmp_path, {**small, "acceptance": {"success_rate": 0.0, "bounds": {"fuel_used": {"max": cut}}}})
    assert main(["sweep", spec, "--workers", "1", "--out", str(tmp_path / "out"), "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "acceptance: 1 of 2 met" in text
    assert f"NOT MET fuel_used <= {cut:g} kg, every flight: {4 - len(over)}/4 flights (outside: #{over[0]} " in text
    checks = json.loads((tmp_path / "out" / "summary.json").read_text())["controllers"][0]["acceptance"]
    assert [c["met"] for c in checks] == [True, False]
    assert [i for i, _ in checks[1]["outside"]] == over
