"""The FLIGHT_ENDED event's values (lander_ros.flight_span): encoded and decoded, old layout too."""
from __future__ import annotations

import pytest

from lander_ros.flight_span import COUNTED_TOPICS, SENSOR_TOPICS, FlightEnd, lockstep_warning


def test_the_values_carry_the_counts_and_the_lockstep_timeouts_and_decode_back() -> None:
    counts = {t: 10 * i + 1 for i, t in enumerate(COUNTED_TOPICS)}
    end = FlightEnd(12.5, "landed", counts, lockstep_timeouts=3)
    values = end.values()
    assert len(values) == 2 + len(COUNTED_TOPICS) + 1 and values[-1] == 3.0
    assert FlightEnd.from_values(values) == end
    assert "3 lockstep timeouts" in end.detail()
    assert "lockstep" not in FlightEnd(1.0, "time-limit", counts).detail()  # none: not mentioned
    # the one sentence lander fly's summary and lander analyse both print
    assert "the sim advanced past 3 states without the autopilot's answer" in lockstep_warning(end.lockstep_timeouts)
    assert lockstep_warning(FlightEnd(1.0, "time-limit", counts).lockstep_timeouts) is None


def test_an_event_recorded_before_the_timeout_count_decodes_with_none() -> None:
    counts = {t: 5 for t in COUNTED_TOPICS}
    old = [2.0, 0.0] + [5.0] * len(COUNTED_TOPICS)  # the older layout: no lockstep-timeout count
    assert FlightEnd.from_values(old) == FlightEnd(2.0, "time-limit", counts, 0)


def test_a_flight_with_sensors_carries_their_counts_after_the_timeouts_and_one_without_does_not() -> None:
    counts = {t: 10 * i + 1 for i, t in enumerate(COUNTED_TOPICS)}
    plain = FlightEnd(3.0, "time-limit", counts, 2)
    assert len(plain.values()) == 2 + len(COUNTED_TOPICS) + 1 and not plain.has_sensors
    with_sensors = FlightEnd(3.0, "time-limit", counts | {t: 100 + i for i, t in enumerate(SENSOR_TOPICS)}, 2)
    values = with_sensors.values()
    assert values[: len(plain.values())] == plain.values()  # the layout without sensors, then theirs
    assert values[len(plain.values()):] == [100.0 + i for i in range(len(SENSOR_TOPICS))]
    assert FlightEnd.from_values(values) == with_sensors
    assert "/lander/sensors/imu 100" in with_sensors.detail() and "sensors" not in plain.detail()


@pytest.mark.parametrize("values, words", [
    ([1.0, 0.0], "carries 2 values"),
    ([1.0, 7.0] + [0.0] * (len(COUNTED_TOPICS) + 1), "reason 7.0 is not an index"),
])
def test_a_malformed_event_is_named(values: list[float], words: str) -> None:
    with pytest.raises(ValueError, match=words):
        FlightEnd.from_values(values)
