"""`lander analyse` as users run it: a table, JSON, plots; damaged bags give one line, never a traceback."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from .synth import write_flight_bag

REPO = Path(__file__).resolve().parents[2]


def _lander(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", "analyse", *args],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=120)


def test_analyse_prints_json_and_writes_plots(tmp_path: Path) -> None:
    t = np.arange(0, 10, 0.1)
    write_flight_bag(tmp_path / "b", t, 500 + np.exp(-t), -np.exp(-t), demand=[(0.0, 500.0)])
    r = _lander(str(tmp_path / "b"), "--json", "--out", str(tmp_path / "png"))
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    # e(t) = e^{-t} leaves the 0.5 m band at t = ln 2 = 0.693 s: first sample inside is 0.7 s.
    assert doc["flights"][0]["settling_time"] == __import__("pytest").approx(0.7, abs=1e-9)
    assert sorted(p.name for p in (tmp_path / "png").iterdir())[0] == "flight-altitude.png"


def test_an_out_path_that_is_a_file_is_one_clear_line_and_the_file_is_untouched(tmp_path: Path) -> None:
    t = np.arange(0, 10, 0.1)
    write_flight_bag(tmp_path / "b", t, 500 + np.exp(-t), -np.exp(-t), demand=[(0.0, 500.0)])
    readme = tmp_path / "README.md"
    readme.write_text("mine\n")
    r = _lander(str(tmp_path / "b"), "--out", str(readme))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines() == [f"lander analyse: --out {readme}: not a folder (a file of that name "
                                             "exists); give a folder for the plots"]
    assert readme.read_text() == "mine\n"


def test_analyse_on_corrupt_and_missing_bags_is_one_clear_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "bad.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 100)
    (bad / "metadata.yaml").write_text("rosbag2_bagfile_information: {version: 9}\n")
    for target in (bad, tmp_path / "missing"):
        r = _lander(str(target))
        assert r.returncode == 2
        assert "Traceback" not in r.stderr and r.stderr.startswith("lander analyse: ")
        assert str(target.name) in r.stderr


def test_analyse_on_a_truncated_bag_reports_the_readable_part(tmp_path: Path) -> None:
    n = 6000  # several 1 MiB chunks, see test_bagio
    t = np.arange(n) * 0.1
    write_flight_bag(tmp_path / "b", t, np.full(n, 500.0), np.zeros(n), demand=[(0.0, 500.0)])
    f = next((tmp_path / "b").glob("*.mcap"))
    data = f.read_bytes()
    f.write_bytes(data[: int(len(data) * 0.8)])  # inside the last chunk: its states are lost
    r = _lander(str(tmp_path / "b"), "--json")
    assert r.returncode == 0 and "Traceback" not in r.stderr
    assert "warning" in r.stderr and "truncated or damaged" in r.stderr
    states = json.loads(r.stdout)["flights"][0]["states"]
    assert n // 2 <= states < n
