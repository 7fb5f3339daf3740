"""Sweep spec validation: good specs parse, bad ones raise SweepSpecError naming the key."""
from __future__ import annotations

import pytest

from lander_tools.sweep.spec import SweepSpecError, load_spec, parse_spec


def _good(**over):
    data = {
        "scene": "hover",
        "controllers": ["combined"],
        "flights": 10,
        "seed": 3,
        "end": {"duration": 20.0},
        "dispersions": {
            "initial_tilt": {"normal": {"mean": 0.0, "std": 0.05}},
            "mass_error": {"uniform": {"min": -0.02, "max": 0.02}},
            "thruster_failure": {"probability": 0.1, "time": {"uniform": {"min": 1.0, "max": 5.0}}},
        },
    }
    data.update(over)
    return data


def test_good_spec_parses_into_typed_fields():
    spec = parse_spec(_good())
    assert spec.flights == 10 and spec.seed == 3
    assert spec.controllers[0].name == "combined"
    assert spec.dispersions.initial_tilt.kind == "normal"
    assert spec.dispersions.initial_tilt.b == 0.05
    assert spec.dispersions.thruster_failure.probability == 0.1
    assert spec.end.duration == 20.0


def test_acceptance_parses_into_typed_bounds():
    spec = parse_spec(_good(metrics=["fuel_used", "hover_error"], acceptance={
        "success_rate": 0.95, "success_wilson_low": 0.9,
        "bounds": {"fuel_used": {"max": 12.5}, "hover_error": {"min": -2.0, "max": 2.0}}}))
    a = spec.acceptance
    assert (a.success_rate, a.success_wilson_low) == (0.95, 0.9)
    assert [(b.metric, b.min, b.max) for b in a.bounds] == [("fuel_used", None, 12.5), ("hover_error", -2.0, 2.0)]
    assert parse_spec(_good()).acceptance.bounds == ()  # none asked: nothing checked


def test_scenario_number_is_accepted_as_a_scene_alias():
    assert parse_spec(_good(scene=7)).scene == "7"


@pytest.mark.parametrize(
    "data, key",
    [
        (_good(flihgts=3), r"flihgts: unknown key"),
        (_good(flights=-5), r"flights: must be >= 1, got -5"),
        (_good(flights=0), r"flights: must be >= 1"),
        (_good(flights=2.5), r"flights: expected an integer"),
        (_good(seed=-1), r"seed: must be >= 0"),
        (_good(dispersions={"initial_tilt": {"normal": {"mean": 0.0, "std": -0.1}}}),
         r"dispersions\.initial_tilt\.normal\.std: a standard deviation must be >= 0"),
        (_good(dispersions={"initial_altitude": {"uniform": {"min": 5.0, "max": -5.0}}}),
         r"dispersions\.initial_altitude\.uniform\.min: min \(5\.0\) is greater than max"),
        (_good(dispersions={"initial_tilt": {"gaussian": {"mean": 0, "std": 1}}}),
         r"dispersions\.initial_tilt: expected exactly one of normal, uniform, fixed"),
        (_good(dispersions={"initial_tilt": {"normal": {"mean": 0, "sigma": 1}}}),
         r"dispersions\.initial_tilt\.normal\.sigma: unknown key"),
        (_good(dispersions={"tilt": 0.1}), r"dispersions\.tilt: unknown key"),
        (_good(dispersions={"mass_error": {"uniform": {"min": -1.5, "max": 0.0}}}),
         r"dispersions\.mass_error: relative error must stay above -1"),
        (_good(dispersions={"wind_gust": {"uniform": {"min": -1.0, "max": 1.0}}}),
         r"dispersions\.wind_gust: must be >= 0"),
        (_good(dispersions={"thruster_failure": {"probability": 1.5}}),
         r"dispersions\.thruster_failure\.probability: a probability must be in \[0, 1\]"),
        (_good(end={"duration": -1.0}), r"end\.duration: must be > 0"),
        (_good(end={"durration": 1.0}), r"end\.durration: unknown key"),
        (_good(end={"duration": 5.0, "hover_window": 10.0}), r"end\.hover_window"),
        (_good(metrics=["touchdown_sped"]), r"metrics\[0\]: unknown metric 'touchdown_sped'"),
        (_good(controllers=[]), r"controllers: empty"),
        (_good(controllers=["combined", "combined"]), r"controllers: controller labels must differ"),
        (_good(controllers=[{"name": "combined", "gains": {}}]), r"controllers\[0\]\.gains: unknown key"),
        (_good(acceptance={"success": 0.95}), r"acceptance\.success: unknown key"),
        (_good(acceptance={"success_rate": 95}), r"acceptance\.success_rate: a fraction in \[0, 1\]"),
        (_good(acceptance={"bounds": {"fuel_ratio": {"max": 1.05}}}),
         r"acceptance\.bounds\.fuel_ratio: not among the sweep's metrics"),
        (_good(metrics=["fuel_used"], acceptance={"bounds": {"fuel_used": {"below": 1.0}}}),
         r"acceptance\.bounds\.fuel_used\.below: unknown key"),
        (_good(metrics=["fuel_used"], acceptance={"bounds": {"fuel_used": {}}}),
         r"acceptance\.bounds\.fuel_used: give max, min or both"),
        (_good(metrics=["fuel_used"], acceptance={"bounds": {"fuel_used": {"min": 2.0, "max": 1.0}}}),
         r"acceptance\.bounds\.fuel_used: min \(2\) is above max \(1\)"),
    ],
)
def test_bad_spec_raises_an_error_naming_the_key(data, key):
    with pytest.raises(SweepSpecError, match=key):
        parse_spec(data, "bad.yaml")


def test_missing_required_key_is_named():
    data = _good()
    del data["flights"]
    with pytest.raises(SweepSpecError, match=r"flights: missing"):
        parse_spec(data)


def test_load_spec_names_the_file(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("scene: hover\ncontroller: combined\nflights: -2\n")
    with pytest.raises(SweepSpecError, match=r"s\.yaml: flights: must be >= 1"):
        load_spec(p)
    assert issubclass(SweepSpecError, ValueError)


def test_shipped_specs_are_valid():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "sweeps"
    files = sorted(root.glob("*.yaml"))
    assert files, "sweeps/*.yaml should ship at least one spec"
    for f in files:
        load_spec(f)
