"""The scene section ``sensors:`` (lander_sim/sensors/suite.py through the scene loader): what a scene asks
for is on with its parameters checked against each sensor's table, nothing else is, errors name the key."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from lander_sim.scenes import list_scenes, load_scene
from lander_sim.scenes.loader import SceneError, parse_scene
from lander_sim.sensors.params import defaults
from lander_sim.sensors.suite import SENSORS


def _scene(sensors):
    data = {"vehicle": {"preset": "lander"}, "dt": 0.1, "initial": {"position_W": [0.0, -3386500.0, 0.0]},
            "models": {"gravity": {"kind": "inverse-square"}}, "sensors": sensors}
    return parse_scene(data, "s.yaml")


def test_no_section_no_sensors_in_every_packaged_scene() -> None:
    """A packaged scene without a ``sensors:`` section has none; one with it has exactly those it lists."""
    for info in list_scenes():
        section = yaml.safe_load(Path(info.path).read_text()).get("sensors")
        sensors = load_scene(info.path).sensors
        if section is None:
            assert sensors is None, info.name
        else:
            assert sensors is not None and set(sensors.sections) == set(section) - {"seed"}, info.name
    assert set(load_scene("landing-sensors").sensors.sections) == {"imu", "star_tracker", "altimeter", "doppler"}


def test_only_the_sensors_asked_for_are_on_with_defaults_and_overrides() -> None:
    s = _scene({"seed": 4, "imu": {}, "altimeter": {"max_range": 2000.0}, "doppler": None, "star_tracker": False})
    assert s.sensors is not None
    assert set(s.sensors.sections) == {"imu", "altimeter"}
    assert s.sensors.seed == 4
    assert s.sensors.sections["imu"] == defaults(SENSORS["imu"][0])
    assert s.sensors.sections["altimeter"]["max_range"] == 2000.0


def test_the_beam_direction_is_normalised() -> None:
    s = _scene({"altimeter": {"beam_B": [0.0, 3.0, -4.0]}})
    assert s.sensors.sections["altimeter"]["beam_B"] == pytest.approx((0.0, 0.6, -0.8))


@pytest.mark.parametrize(("sensors", "match"), [
    ({"sonar": {}}, r"s.yaml: sensors.sonar: unknown key"),
    ({"imu": {"gyro_bias": -1.0}}, r"sensors.imu.gyro_bias: expected a number >= 0"),
    ({"imu": {"rate": 0.0}}, r"sensors.imu.rate: expected a number > 0"),
    ({"imu": {"rate": "fast"}}, r"sensors.imu.rate: expected a number"),
    ({"altimeter": {"beam_B": [0, 0, 0]}}, r"sensors.altimeter.beam_B: expected a non-zero direction"),
    ({"seed": -1}, r"sensors.seed: expected an integer"),
    ({"doppler": {"range": 1.0}}, r"sensors.doppler.range: unknown key"),
])
def test_bad_sections_name_the_key(sensors, match) -> None:
    with pytest.raises(SceneError, match=match):
        _scene(sensors)


def test_every_default_passes_its_own_table() -> None:
    for key, (table, _) in SENSORS.items():
        for p in table:
            if not isinstance(p.default, tuple):
                assert p.check(p.default) is None, f"{key}.{p.name}"


def test_the_user_guide_holds_every_sensors_parameter_table() -> None:
    from pathlib import Path

    from lander_sim.sensors.params import table_markdown

    doc = (Path(__file__).resolve().parents[2] / "docs" / "estimation.md").read_text()
    for key, (table, _) in SENSORS.items():
        assert table_markdown(table) in doc, f"docs/estimation.md: the {key} table differs from its PARAMS"
