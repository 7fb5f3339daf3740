"""The de-orbit mission's phase machine (lander_autopilot.controllers.deorbit.phases), without a flight:
every (phase, event) pair, and each event's condition at and around its threshold."""
from __future__ import annotations

import itertools

import pytest

from lander_autopilot.controllers.deorbit.phases import (
    TRANSITIONS,
    Event,
    Phase,
    PhaseError,
    PhaseMachine,
    burn_due,
    in_atmosphere,
    next_phase,
    periapsis_reached,
    settled,
)
from lander_sim.physics import constants as c

S, B, C, E, P, D, H, L = (Phase.SLEW, Phase.BURN, Phase.COAST, Phase.ENTRY, Phase.PARACHUTE, Phase.POWERED,
                          Phase.HOVER, Phase.LANDING)

#: Every pair that moves the mission on, and where to; every other pair is refused.
TABLE = {
    (S, Event.BURN_START): B,
    (B, Event.PERIAPSIS): C,
    (C, Event.ATMOSPHERE): E,
    (E, Event.CHUTE_OPENED): P,
    (E, Event.BRAKING): D,
    (P, Event.BRAKING): D,
    (D, Event.SETTLED): H,
    (H, Event.LAND): L,
}


@pytest.mark.parametrize("phase, event", list(itertools.product(Phase, Event)))
def test_every_phase_and_event_pair_moves_on_by_the_table_or_is_refused(phase, event):
    machine = PhaseMachine(phase)
    if (phase, event) in TABLE:
        assert machine.fire(12.5, event, "why") is TABLE[(phase, event)]
        assert machine.phase is TABLE[(phase, event)]
        assert machine.log.transitions == [(12.5, phase, TABLE[(phase, event)], "why")]
    else:
        with pytest.raises(PhaseError, match=f"{event.value!r} does not leave phase {phase.value!r}"):
            machine.fire(12.5, event, "why")
        assert machine.phase is phase and machine.log.transitions == []  # a refused event changes nothing


def test_the_table_is_the_modules_and_only_moves_forward():
    assert TRANSITIONS == TABLE
    order = list(Phase)
    assert all(order.index(to) > order.index(frm) for (frm, _), to in TRANSITIONS.items())


def test_a_flight_from_orbit_visits_every_phase_in_order():
    machine = PhaseMachine()
    for t, event in enumerate((Event.BURN_START, Event.PERIAPSIS, Event.ATMOSPHERE, Event.CHUTE_OPENED,
                               Event.BRAKING, Event.SETTLED, Event.LAND)):
        machine.fire(float(t), event, event.value)
    assert [to for _, _, to, _ in machine.log.transitions] == list(Phase)[1:]
    assert next_phase(E, Event.BRAKING) is D  # a braking entry (the chute never opened) skips the parachute


def test_a_note_keeps_the_phase():
    machine = PhaseMachine(D)
    machine.note(3.0, "MPC refused the handover")
    assert machine.phase is D and machine.log.transitions == [(3.0, D, D, "MPC refused the handover")]


def test_conditions_fire_at_their_thresholds():
    assert not burn_due(59.9, 60.0) and burn_due(60.0, 60.0)
    target = 50e3
    assert periapsis_reached(c.MARS_RADIUS + target, target) and not periapsis_reached(c.MARS_RADIUS + target + 1.0, target)
    assert in_atmosphere(c.EXOSPHERE_ALTITUDE - 1.0) and not in_atmosphere(c.EXOSPHERE_ALTITUDE)


@pytest.mark.parametrize("error, climb, expected", [
    (0.0, 0.0, True),  # at rest on the demand
    (2.0, -0.2, True),  # at the band's top, at its speed
    (2.01, 0.0, False),  # over the band
    (1.0, -0.21, False),  # in the band, still falling faster than the speed
    (1.0, 0.21, False),  # in the band, climbing faster than the speed
    (-1.9, 0.0, True),
    (-5.0, 3.0, True),  # under the band: any climb rate from -speed up (the hover climbs back)
    (-5.0, -0.21, False),  # under the band and still falling
])
def test_the_fall_is_settled_in_the_band_at_its_speed_or_under_it_not_falling(error, climb, expected):
    assert settled(error, climb, 2.0, 0.2) is expected
