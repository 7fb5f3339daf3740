"""The ROS path's hand-over of a case: scene file with the dispersed initial state, timeline."""
from __future__ import annotations

import numpy as np
import pytest

from lander_sim.scenes import load_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import apply_case, nominal_scene
from lander_tools.sweep.ros_path import NotRepresentable, scene_file_for_case
from lander_tools.sweep.spec import parse_spec

from .conftest import SMALL

STATE_ONLY = {**SMALL, "dispersions": {k: SMALL["dispersions"][k] for k in (
    "initial_tilt", "initial_body_rate", "initial_altitude", "initial_velocity", "wind_mean")}}


def test_scene_file_round_trips_the_dispersed_initial_state(tmp_path):
    spec = parse_spec(STATE_ONLY)
    path = scene_file_for_case(spec, 2, tmp_path)
    written = load_scene(path)
    expected = apply_case(nominal_scene(spec), draw_case(spec, 2, 4)).initial_state
    # YAML carries floats with repr precision; the loader re-normalises the quaternion (1 ulp).
    assert np.allclose(written.initial_state, expected, rtol=1e-15, atol=1e-15)


def test_vehicle_dispersions_are_refused_by_name(tmp_path):
    spec = parse_spec({**STATE_ONLY, "dispersions": {"mass_error": {"fixed": 0.01}}})
    with pytest.raises(NotRepresentable, match=r"dispersions\.mass_error"):
        scene_file_for_case(spec, 0, tmp_path)
