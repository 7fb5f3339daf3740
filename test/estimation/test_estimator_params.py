"""The estimator node's parameter table (lander_autopilot.ros.estimator_config), without ROS: the
docs hold the table generated from it, and a bad value is refused with a line naming it."""
from __future__ import annotations

from pathlib import Path

import pytest

from lander_autopilot.ros.estimator_config import PARAMETERS, SPECS, initial_sigma, parameter_table
from lander_ros.params import check_value

DOCS = Path(__file__).resolve().parents[2] / "docs" / "estimation.md"


def test_the_docs_hold_the_parameter_table() -> None:
    assert parameter_table() in DOCS.read_text()


def test_every_default_is_accepted() -> None:
    for p in PARAMETERS:
        assert check_value(SPECS, p.name, p.default) is None, p.name


@pytest.mark.parametrize(("name", "value", "words"), [
    ("seed", -2, "integer >= 0"),
    ("seed", 1.5, "integer >= 0"),
    ("initial_position_sigma", 0.0, "> 0"),
    ("initial_attitude_sigma", float("inf"), "> 0"),
    ("scene", 3, "string"),
    ("nonsense", 1, "unknown parameter"),
])
def test_a_bad_value_is_refused_naming_the_parameter(name: str, value: object, words: str) -> None:
    why = check_value(SPECS, name, value)
    assert why is not None and name in why and words in why, why


def test_the_initial_sigmas_in_si_units() -> None:
    values = {p.name: p.default for p in PARAMETERS}
    pos, vel, att = initial_sigma(values)
    assert (pos, vel) == (10.0, 0.5) and att == pytest.approx(0.017453292519943295)
