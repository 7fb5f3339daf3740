"""The ROS path's hand-over of a case: the scene file carries every dispersion; rows compare."""
from __future__ import annotations

import math

import numpy as np
import yaml

from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.ros_path import compare_rows, scene_file_for_case
from lander_tools.sweep.spec import parse_spec

from .conftest import SMALL


def test_scene_file_is_the_core_only_scene_for_every_dispersion(tmp_path, small_spec):
    # SMALL disperses everything (incl. mass, inertia, thrust, gusts, failure): the file the
    # simulator node loads must be the very scene core-only flies, field for field.
    for i in range(small_spec.flights):
        written = load_scene(scene_file_for_case(small_spec, i, tmp_path))
        core = flown_scene(small_spec, draw_case(small_spec, i, 4))
        assert written.vehicle.dry_mass == core.vehicle.dry_mass and written.gust == core.gust
        assert written.vehicle.gyration_sq == core.vehicle.gyration_sq
        assert [t.max_thrust for t in written.vehicle.thrusters] == [t.max_thrust for t in core.vehicle.thrusters]
        assert written.thruster_failures == core.thruster_failures and written.wind_W == core.wind_W
        # YAML carries floats with repr precision, so the state is bit-identical.
        assert np.array_equal(written.initial_state, core.initial_state)


def test_a_flight_from_the_written_scene_is_bit_identical(tmp_path, small_spec):
    # Same scene -> same Simulation -> same states, gusts and failure: 80 steps under constant
    # throttles must match to the last bit (the nodes add only the middleware).
    i = next(i for i in range(small_spec.flights) if draw_case(small_spec, i, 4).failed_thruster >= 0)
    a = Simulation(load_scene(scene_file_for_case(small_spec, i, tmp_path)))
    b = Simulation(flown_scene(small_spec, draw_case(small_spec, i, 4)))
    for sim in (a, b):
        sim.set_throttles([0.5] * 4)
        sim.step(80)
    assert np.array_equal(a.y, b.y) and a.failed_thrusters == b.failed_thrusters


def test_dispersed_vehicle_keys_are_in_the_file(tmp_path):
    spec = parse_spec({**SMALL, "dispersions": {"mass_error": {"fixed": 0.01},
                                                "thruster_failure": {"probability": 1.0, "time": {"fixed": 2.0}}}})
    data = yaml.safe_load(scene_file_for_case(spec, 0, tmp_path).read_text())
    assert data["vehicle"]["dry_mass_scale"] == 1.01
    assert data["vehicle"]["failures"][0]["time"] == 2.0
    assert nominal_scene(spec).vehicle.dry_mass * 1.01 == load_scene(tmp_path / f"{data['name']}.yaml").vehicle.dry_mass


def test_compare_rows_flags_outcome_and_metric_differences_only_beyond_round_off():
    a = {"index": 0, "controller": "c", "outcome": "ok", "hover_error": 0.25, "touchdown_speed": math.nan}
    assert compare_rows(a, dict(a), ("hover_error", "touchdown_speed")) == []
    # 1e-12 relative is round-off; 1e-6 is a different flight.
    assert compare_rows(a, {**a, "hover_error": 0.25 * (1 + 1e-12)}, ("hover_error",)) == []
    assert len(compare_rows(a, {**a, "hover_error": 0.25 * (1 + 1e-6)}, ("hover_error",))) == 1
    assert "outcome" in compare_rows(a, {**a, "outcome": "tipped"}, ())[0]
