"""What `lander fly` prints is in the user's words: an event's sentence without the key of its
numbers (that key is for programs: lander_tools.fly.supervisor.event_values reads it), a scene
given by its scenario number named as well; and a paused flight is not called stalled."""
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


def test_a_paused_flight_is_not_stalled_while_the_simulator_still_reports() -> None:
    from lander_tools.fly.supervisor import stall_reason

    limit, t = 30.0, 12.3
    assert stall_reason(100.0, 75.0, False, 99.0, t, limit) is None  # a state 25 s ago
    running = stall_reason(100.0, 60.0, False, 99.0, t, limit)  # running, no state for 40 s
    assert running == "no state from the simulator for 30.0 s at t = 12.300 s"
    assert stall_reason(1000.0, 60.0, True, 999.0, t, limit) is None  # paused for 15 min, reporting
    gone = stall_reason(1000.0, 60.0, True, 960.0, t, limit)  # paused, then silent for 40 s
    assert gone == "no word from the simulator for 30.0 s (paused at t = 12.300 s)"


def test_the_last_state_says_na_for_what_the_scene_has_not() -> None:
    """The summary's last state follows lander analyse's rules (lander_tools.metrics_fit): a fixed
    pivot (r = 0) has no altitude or tilt, a body without thrusters no fuel; a lander has all."""
    import math

    from lander_interfaces.msg import LanderState

    from lander_tools.fly.summary import final_state

    rotor = LanderState()
    rotor.orientation.w, rotor.fuel_mass, rotor.throttles = 1.0, 0.0, []
    f = final_state(rotor)
    assert math.isnan(f["altitude"]) and math.isnan(f["tilt_deg"]) and math.isnan(f["fuel"])
    lander = LanderState()
    lander.position.z, lander.altitude, lander.orientation.w = 3.4e6 + 500.0, 500.0, 1.0
    lander.fuel_mass, lander.throttles = 40.5, [0.5, 0.5, 0.5, 0.5]
    f = final_state(lander)
    assert (f["altitude"], f["fuel"]) == (500.0, 40.5)
