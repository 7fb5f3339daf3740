"""What `lander fly` prints is in the user's words: an event's sentence without the key of its
numbers (that key is for programs: lander_tools.fly.supervisor.event_values reads it), a scene
given by its scenario number named as well."""
from __future__ import annotations

from types import SimpleNamespace

from lander_tools.fly.checks import scene_label
from lander_tools.fly.supervisor import event_text, event_values


def test_an_event_line_drops_the_key_of_its_values_and_the_values_stay_readable_by_name() -> None:
    detail = ("crashed at t = 22.589 s (crash): descent rate 58.10 m/s, ground speed 4.52 m/s, tilt 56.69 deg, "
              "fuel left 93.43 kg [values: t_impact, descent_rate, ground_speed, tilt_deg, fuel_left]")
    assert event_text(detail) == detail.split(" [values: ")[0]
    msg = SimpleNamespace(detail=detail, values=[22.589, 58.1, 4.52, 56.69, 93.43])
    assert event_values(msg)["descent_rate"] == 58.1
    plain = "controller 'deorbit' mode 'deorbit-slew' -> 'deorbit-burn'"
    assert event_text(plain) == plain  # no values: unchanged


def test_a_scene_given_by_its_scenario_number_is_named() -> None:
    assert scene_label("7") == "'hover' (scenario 7)"
    assert scene_label("hover") == "'hover'"
    assert scene_label("flights/x.yaml") == "'flights/x.yaml'"
