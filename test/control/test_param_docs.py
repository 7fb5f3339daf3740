"""The controllers' parameter tables (lander_autopilot.controllers.params) and the docs generated
from them: every ``<!-- params: NAME -->`` block in docs/*.md is exactly ``lander controllers NAME
--markdown``; the tables validate what the constructors take; ``lander controllers`` prints them."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from lander_autopilot.controllers import ControllerError, make_controller
from lander_autopilot.controllers.registry import BUILTINS, parameter_table
from lander_sim.scenes import load_scene
from lander_tools.commands.controllers import blocks, markdown, regenerate

DOCS = Path(__file__).resolve().parents[2] / "docs"
TABLED = sorted(BUILTINS)  # every built-in law has a table (test_every_built_in_law_has_a_table)


def test_every_generated_block_in_the_docs_is_its_controllers_table():
    drift = []
    for path in sorted(DOCS.glob("*.md")):
        text = path.read_text()
        lines = text.split("\n")
        for name, start, end in blocks(text):
            try:
                want = markdown(name)
            except ValueError as exc:
                drift.append(f"{path.name}: block for {name!r}: {exc}")
                continue
            if "\n".join(lines[start:end]) != want:
                drift.append(f"{path.name}: the {name!r} table differs from 'lander controllers {name} --markdown'")
    assert not drift, "; ".join(drift) + " (regenerate: ./dev controllers --update-docs)"


def test_a_block_is_regenerated_in_place_and_an_unclosed_one_is_named():
    doc = "# Guide\n\nText.\n<!-- params: landing -->\n| stale |\n<!-- /params -->\nMore text.\n"
    new = regenerate(doc)
    assert new.startswith("# Guide\n\nText.\n<!-- params: landing -->\n| parameter | default |")
    assert new.endswith(markdown("landing") + "\n<!-- /params -->\nMore text.\n")
    assert regenerate(new) == new  # a generated doc is left as it is
    assert blocks(new) == [("landing", 4, 4 + len(markdown("landing").split("\n")))]
    with pytest.raises(ValueError, match="line 2: '<!-- params: deorbit -->' has no '<!-- /params -->'"):
        blocks("x\n<!-- params: deorbit -->\n| a |\n")


def test_every_built_in_law_has_a_table():
    assert [name for name in sorted(BUILTINS) if parameter_table(name) is None] == []


def test_every_built_in_law_has_its_generated_table_in_the_docs():
    documented = {name for path in DOCS.glob("*.md") for name, _, _ in blocks(path.read_text())}
    missing = sorted(set(BUILTINS) - documented)
    assert not missing, f"no '<!-- params: NAME -->' block in docs/*.md for {', '.join(missing)}"


@pytest.mark.parametrize("name", TABLED)
def test_each_tables_defaults_build_the_law_and_a_row_names_its_unit_range_and_meaning(name):
    table = parameter_table(name)
    assert table is not None
    for row in table.rows:
        assert row.unit and row.range and row.meaning, row.name
        assert "\n" not in row.meaning and len(row.meaning) < 120, row.name  # one line
    vehicle = load_scene("deorbit").vehicle
    explicit = make_controller(name, vehicle, **table.defaults())  # every default given: the same law
    assert type(explicit) is type(make_controller(name, vehicle))


@pytest.mark.parametrize("name, key, bad, range_text", [
    ("deorbit", "chute_margin", 1.5, "(0, 1]"),
    ("deorbit", "brake_fraction", 1.0, "(0, 1)"),
    ("deorbit", "descent_pole", 2.0, "negative"),
    ("deorbit", "learn_headroom", "yes", "true or false"),
    ("deorbit-mpc", "handover_fraction", 0.0, "positive"),
    ("deorbit-mpc", "coast_collective", 1.0, "[0, 1)"),
    ("deorbit-mpc", "glide_slope", math.pi, "[0, pi/2)"),
    ("landing", "touchdown_rate", -0.25, "positive"),
    ("landing", "max_tilt", 1.4, "1.3 rad"),
    ("baseline", "kp", "fast", "finite"),
    ("altitude", "poles", [0.5, -1.0], "negative real part"),
    ("altitude", "p_only", "yes", "true or false"),
    ("altitude-integral", "poles", [-0.9, -1.1], "3 poles"),
    ("attitude-quaternion", "design_fuel", 0.0, "positive"),
    ("integral", "altitude_poles", [-0.9, -1.1], "3 poles"),
    ("combined", "attitude_poles", [-1.0] * 5, "6 poles"),
    ("combined-quaternion", "design_fuel", -5.0, "positive"),
    ("lqr", "R_altitude", 0.0, "positive"),
    ("lqr", "Q_attitude", [100.0] * 5 + [-1.0], ">= 0"),
    ("ground-speed", "max_tilt", 1.4, "1.3 rad"),
    ("ground-speed", "velocity_lqr", [1.0, 1.0, 0.0], "r > 0"),
])
def test_a_bad_value_is_refused_naming_the_parameter_the_value_and_the_range(name, key, bad, range_text):
    with pytest.raises(ControllerError) as err:
        make_controller(name, load_scene("deorbit").vehicle, **{key: bad})
    message = str(err.value)
    assert message.startswith(f"{key}: expected")
    assert repr(bad) in message and range_text in message


def test_a_name_means_one_thing_across_the_laws():
    # the MPC's handover fraction is not the braking limb's fraction: it has its own name
    mpc = parameter_table("deorbit-mpc")
    assert mpc is not None and "handover_fraction" in mpc and "brake_fraction" not in mpc
    with pytest.raises(ControllerError, match="unknown parameter.*brake_fraction"):
        make_controller("deorbit-mpc", load_scene("deorbit").vehicle, brake_fraction=0.5)
    # a key both laws take means the same there: the same row
    deorbit = parameter_table("deorbit")
    assert deorbit is not None
    for key in set(deorbit.names) & set(mpc.names) - {"axis_limit"}:
        assert deorbit[key] is mpc[key], key
    # and limb_time has one default, the guidance library's and the law's
    from lander_autopilot.guidance.descent_mpc import MpcSettings
    assert MpcSettings().limb_time == mpc["limb_time"].default


def _lander(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", "controllers", *args], capture_output=True,
                          text=True, timeout=120, check=False)


def test_lander_controllers_lists_prints_a_table_and_its_markdown():
    listing = _lander()
    assert listing.returncode == 0, listing.stderr
    assert {line.split()[0] for line in listing.stdout.splitlines()} >= {"deorbit", "deorbit-mpc", "landing", "combined"}
    table = _lander("deorbit")
    assert table.returncode == 0 and table.stdout.splitlines()[0].split() == ["name", "default", "unit", "range", "meaning"]
    assert any(line.split()[:2] == ["stop_above", "1.75"] for line in table.stdout.splitlines())
    md = _lander("deorbit-mpc", "--markdown")
    assert md.returncode == 0 and md.stdout == markdown("deorbit-mpc") + "\n"
    summed = _lander("combined")  # a law made of parts: its parts' rows under its own names
    assert summed.returncode == 0 and any(line.split()[:2] == ["altitude_poles", "[-0.9,"] for line in summed.stdout.splitlines())
    unknown = _lander("pid")
    assert unknown.returncode == 2 and "unknown controller 'pid'" in unknown.stderr
