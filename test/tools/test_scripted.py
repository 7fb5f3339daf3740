"""Scripted-flight files: the shipped ones load; bad ones fail with the file, entry and key named."""
from __future__ import annotations

import io
from pathlib import Path

import pytest

from lander_tools.fly.checks import shipped_flights
from lander_tools.fly.plan import FlightPlan, LaunchError, pilot_mode
from lander_tools.progress import Progress
from lander_tools.scripted import ScriptError, is_script, load_script, parse_script

GOOD = {"scene": "hover", "end": {"time": 10}}


def test_every_shipped_flight_loads_and_names_a_known_scene() -> None:
    from lander_sim.scenes import load_scene

    flights = shipped_flights()
    names = {f.stem for f in flights}
    # The shipped flights (docs/flying.md): seed 1 spin and spin-up, seed 2 P-only, hover, steps, wind, swap.
    assert {"seed1-scenario8-spin", "seed1-scenario8-spin-up", "seed2-scenario7-p-only", "seed2-scenario7-hover",
            "seed2-scenario7-altitude-steps", "seed2-scenario7-wind", "seed2-scenario7-controller-swap"} <= names
    for f in flights:
        s = load_script(f)
        assert is_script(f) and s.name == f.stem and s.duration > 0
        load_scene(s.scene)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"end": {"time": 1}}, "missing key 'scene'"),
        ({"scene": "hover"}, "missing key 'end'"),
        ({**GOOD, "end": {"time": -1}}, r"end.time = -1.0: must be > 0"),
        ({**GOOD, "spead": 1}, "unknown key.*spead"),
        ({**GOOD, "timeline": [{"demand_altitude": 5}]}, r"timeline\[0\]: missing key 't'"),
        ({**GOOD, "timeline": [{"t": 1, "gust": 5}]}, r"timeline\[0\]: unknown key.*gust"),
        ({**GOOD, "timeline": [{"t": 1, "wind": [1, 2]}]}, r"timeline\[0\].wind: expected \[x, y, z\]"),
        ({**GOOD, "timeline": [{"t": 1, "throttle": [1.5]}]}, r"every throttle must be in \[0, 1\]"),
        ({**GOOD, "timeline": [{"t": 2, "throttle": [0.5], "until": 1}]}, "must be later than t = 2"),
        ({**GOOD, "timeline": [{"t": 2, "wind": [0, 0, 0], "demand_altitude": 3}]}, "exactly one action"),
        ({**GOOD, "record": {"storage": "bag"}}, "record.storage = 'bag': choose mcap or sqlite3"),
    ],
)
def test_bad_scripts_name_the_key(data: dict, match: str) -> None:
    with pytest.raises(ScriptError, match=match):
        parse_script(data, "f.yaml")


def test_unreadable_files_are_script_errors(tmp_path: Path) -> None:
    with pytest.raises(ScriptError, match="cannot read"):
        load_script(tmp_path / "none.yaml")
    (tmp_path / "x.yaml").write_text("scene: [unclosed")
    with pytest.raises(ScriptError, match="not valid YAML"):
        load_script(tmp_path / "x.yaml")


def test_plans_choose_who_answers_the_sim() -> None:
    s = parse_script({**GOOD, "controller": "none", "timeline": [{"t": 1, "throttle": [0.2], "until": 2}]})
    # No autopilot but throttle overrides: the launcher answers in lockstep so they land on their tick.
    assert pilot_mode(s.plan(), None)
    assert not pilot_mode(parse_script({**GOOD, "controller": "combined"}).plan(), "combined")
    with pytest.raises(LaunchError, match="speed = -1"):
        FlightPlan(scene="hover", speed=-1)
    with pytest.raises(LaunchError, match="duration = 0"):
        FlightPlan(scene="hover", duration=0)


def test_progress_is_quiet_off_a_terminal_and_says_time_rtf_altitude() -> None:
    buf = io.StringIO()  # not a TTY
    p = Progress(stream=buf, total=100.0)
    p.update(0.0, 500.0)
    p.update(50.0, 510.0)
    p.finish()
    assert buf.getvalue() == ""
    line = p.line(50.0, 5.0, 510.0)  # 50 s of sim in 5 s of wall time since the first update
    assert "t     50.00 s ( 50%)" in line and "RTF    10.0x" in line and "alt      510.0 m" in line
    shown = io.StringIO()
    q = Progress(stream=shown, enabled=True)
    q.update(1.0, 2.0)
    q.finish()
    assert shown.getvalue().startswith("\rt") and shown.getvalue().endswith("\n")
