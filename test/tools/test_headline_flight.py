"""The README's headline flight as a new user meets it: `lander fly hover --record B` then
`lander analyse B` (the README's headline flight and its summary). One 60 s flight of scenario 7 serves both tests; it
flies as fast as possible (lockstep makes the flight the same at any speed)."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _lander(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300, check=False)


@pytest.fixture(scope="module")
def hover(tmp_path_factory) -> tuple[Path, str]:
    """The bag and the printed summary of `lander fly hover --speed 0 --record B`."""
    where = tmp_path_factory.mktemp("hover")
    r = _lander("fly", "hover", "--speed", "0", "--record", str(where / "B"), "--no-progress", cwd=where)
    assert r.returncode == 0, r.stdout + r.stderr
    return where / "B", r.stdout


def test_analyse_of_the_hover_flight_reports_demand_hover_error_and_draws_the_demand_line(hover) -> None:
    # Item 2: the analysis showed "-" for the demand and every step metric, and no demand line:
    # the scene's demand never reached the bag. The autopilot's status now carries the demand in force.
    from lander_sim.scenes import load_scene
    from lander_tools.analysis import Flight
    from lander_tools.analysis_plots import figures
    from lander_tools.bagio import read_bag

    bag, _ = hover
    r = _lander("analyse", str(bag), "--json", cwd=bag.parent)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["flights"][0]
    ap = load_scene("hover").autopilot
    assert ap is not None
    scene_demand = ap.demand_altitude
    assert m["demand_altitude"] == scene_demand
    f = Flight.from_bag(read_bag(bag))
    assert m["step_size"] == scene_demand - f.altitude[0]  # the flight starts above the demand
    assert m["hover_error_max"] is not None and m["overshoot_percent"] is not None
    # P-only (control reference eq 21) keeps oscillating: it never settles.
    assert m["settling_time"] is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        alt = figures([f])["altitude"]
    demand_lines = [ln for ln in alt.axes[0].get_lines() if ln.get_linestyle() == "--"]
    assert len(demand_lines) == 1
    assert set(demand_lines[0].get_ydata()) == {scene_demand}
    assert demand_lines[0].get_xdata()[-1] == f.t[-1]  # drawn over the whole flight


def test_readme_sample_summary_is_what_the_hover_flight_prints(hover) -> None:
    # Item 7: the README showed "20.6 s wall, RTF 2.9x", impossible at the default speed 1.
    _, printed = hover
    readme = (REPO / "README.md").read_text()
    sample = re.search(r"```\n(flight ended: .*?)\n```", readme, re.DOTALL)
    assert sample, "README has no sample summary block"
    lines = sample.group(1).splitlines()
    # The flight itself is deterministic: what follows the first line (the last state) is printed
    # exactly as in the README.
    assert len(lines) > 1 and all(ln in printed.splitlines() for ln in lines[1:]), f"README: {lines}\nprinted: {printed}"
    ended = next(ln for ln in printed.splitlines() if ln.startswith("flight ended:"))

    def shape(line: str) -> str:
        return re.sub(r"\d+(\.\d+)?", "N", line)

    # Same wording; the wall-clock figures (wall time, real-time factor) differ from run to run.
    assert shape(lines[0]) == shape(ended), f"README: {lines[0]}\nprinted: {ended}"
    sim_figures = re.findall(r"t = [0-9.]+ s|\d+ states", ended)
    assert sim_figures and all(x in lines[0] for x in sim_figures), (sim_figures, lines[0])
    # At the default speed 1 the simulation is paced to the wall clock: it cannot run faster.
    rtf = float(re.search(r"([0-9.]+)x\b", lines[0]).group(1))
    assert rtf <= 1.0
