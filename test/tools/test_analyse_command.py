"""`lander analyse` as users run it: a table, JSON, plots; damaged bags and unusable output paths give
one line, never a traceback; on real flights of the seed-1 scenes, figures that fit the scene."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lander_tools.analysis import Flight
from lander_tools.analysis_plots import figures
from lander_tools.bagio import read_bag
from lander_tools.metrics_fit import scene_facts

from .synth import write_flight_bag

REPO = Path(__file__).resolve().parents[2]


def _lander(*args: str, verb: str = "analyse") -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", verb, *args],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=240)


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


@pytest.mark.parametrize(("out", "prefix", "why"), [
    ("README.md/plots", "flight", "README.md is a file, so no folder can be made under it"),
    ("png", "sub/flight", "--prefix 'sub/flight': give a plain file-name start"),
])
def test_every_output_path_is_checked_before_use(tmp_path: Path, out: str, prefix: str, why: str) -> None:
    t = np.arange(0, 10, 0.1)
    write_flight_bag(tmp_path / "b", t, 500 + np.exp(-t), -np.exp(-t), demand=[(0.0, 500.0)])
    (tmp_path / "README.md").write_text("mine\n")
    r = _lander(str(tmp_path / "b"), "--out", str(tmp_path / out), "--prefix", prefix)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lander analyse: ") and why in lines[0]
    assert r.stdout == "" and not (tmp_path / "png").exists()  # refused before anything was read or made


#: Seed 1's fixed-pivot scenes and scenario 8's free space (canted thrusters), flown by the real nodes for 10 s and recorded under names that do
#: not say which scene they are (the analysis must read the scene from the bag, not its name).
FLOWN = {"spin-top": "rotor-euler", "pendulum-e": "gimbal-lock-pendulum", "pendulum-q": "gimbal-lock-pendulum-quaternion",
         "spin-down": "free-spin-canted"}


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, str]]:
    d = tmp_path_factory.mktemp("flown")
    out = {}
    for bag, scene in FLOWN.items():
        r = _lander(scene, "--speed", "0", "--duration", "10", "--no-progress", "--record", str(d / bag), verb="fly")
        assert r.returncode == 0, r.stdout + r.stderr
        out[bag] = (d / bag, r.stdout)
    return out


def test_a_rotor_gets_its_precessing_z_axis_track_and_no_fuel_or_altitude(flown: dict[str, tuple[Path, str]],
                                                                         tmp_path: Path) -> None:
    bag, _ = flown["spin-top"]
    r = _lander(str(bag), "--json", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["flights"][0]
    # A fixed pivot without thrusters: no altitude, no fuel, nothing to saturate (lander fly's n/a).
    assert (m["final_altitude"], m["fuel_used"], m["saturation_time"]) == (None, None, None)
    assert (tmp_path / "flight-ztrack.png").is_file()
    # The drawn track precesses about the weight's line (world z) at the fast top's rate
    # Omega = m g l / (C omega_3) = 10 N m / (4 kg m^2 * 4 rad/s) = 0.625 rad/s (reference 1,
    # Figure 1); the next term of the expansion is of relative size eps = A m g l / (C omega_3)^2
    # = 2 * 10 / 16^2 = 0.078. Measured over whole nutation periods 2 pi A / (C omega_3) = 0.785 s.
    f = Flight.from_bag(read_bag(bag))
    fig = figures([f])["ztrack"]
    x, y, _ = fig.get_axes()[0].get_lines()[0].get_data_3d()
    t = f.t[::2]  # the track is drawn every second state
    azimuth = np.unwrap(np.arctan2(y, x))
    k = int(np.searchsorted(t, 12 * 2 * np.pi / 8.0))
    rate = (azimuth[k] - azimuth[0]) / t[k]
    assert rate == pytest.approx(0.625, rel=2 * 10 / 16**2)


def test_free_space_gets_no_figure_of_flight_over_a_surface_in_analyse_or_the_summary(
        flown: dict[str, tuple[Path, str]], tmp_path: Path) -> None:
    """Scenario 8 at 1000 R, gravity only, no ground: its "altitude" is a radius of 3.4e9 m and the
    attitude law's upright is not the local vertical, so altitude, climb rate, ground speed, tilt
    and the hover's step figures are n/a in both reports, and no altitude plot is drawn; fuel
    (the thrusters burn it) and the spin rate (the law slows it) are figures of it."""
    bag, fly_out = flown["spin-down"]
    last = next(line for line in fly_out.splitlines() if line.strip().startswith("last state:"))
    assert last.strip() == ("last state: altitude n/a, climb rate n/a, ground speed n/a, tilt n/a, fuel "
                            + last.rsplit("fuel ", 1)[1])
    assert last.rsplit("fuel ", 1)[1].endswith(" kg")
    r = _lander(str(bag), "--json", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["flights"][0]
    surface = ("final_altitude", "demand_altitude", "step_size", "settling_time", "overshoot_percent",
               "steady_state_error", "hover_error_max")
    assert {k: m[k] for k in surface} == dict.fromkeys(surface)
    assert m["fuel_used"] > 0.0 and m["final_spin_rate"] < 0.8  # the scene starts at 0.8 rad/s
    assert not (tmp_path / "flight-altitude.png").exists() and (tmp_path / "flight-attitude.png").is_file()


def test_gimbal_lock_events_are_counted_as_lander_fly_counts_them(flown: dict[str, tuple[Path, str]]) -> None:
    import re

    for name in ("pendulum-e", "pendulum-q"):
        bag, fly_out = flown[name]
        said = re.search(r"gimbal lock: (\d+) events in all", fly_out)
        fly_count = int(said.group(1)) if said else fly_out.count("near gimbal lock")
        r = _lander(str(bag), "--json")
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)["flights"][0]["gimbal_lock_events"] == fly_count, fly_out
        # The Euler-mode pendulum starts in the lock (theta = 0); with quaternions there is none.
        assert fly_count == (1 if scene_facts({"scene": FLOWN[name]}).attitude == "euler" else 0)


def test_the_euler_pendulums_angles_are_drawn_in_range_with_the_lock_shaded(flown: dict[str, tuple[Path, str]]) -> None:
    f = Flight.from_bag(read_bag(flown["pendulum-e"][0]))
    assert np.max(np.abs(np.degrees(f.euler))) > 360.0  # the integrated angles leave their ranges
    ax = figures([f])["attitude"].get_axes()[0]
    ys = np.concatenate([ln.get_ydata() for ln in ax.get_lines()])
    assert np.all(np.abs(ys) <= 180.0)
    assert ax.patches and {p.get_gid() for p in ax.patches} == {"near gimbal lock"}
