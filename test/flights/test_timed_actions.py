"""Timeline actions are exact in sim time at any speed: at speed 0 (as fast as possible, lockstep)
a demand step scripted at t lands on the first control instant >= t, and the flight ends exactly
on the first instant >= its end time. Checked from the bag against the same controller replayed
here on the recorded states (the autopilot's answers are deterministic, so equality is exact)."""
from __future__ import annotations

import math
from pathlib import Path

from lander_autopilot.controllers import Demand, make_controller
from lander_autopilot.ros.config import scene_autopilot
from lander_autopilot.ros.convert import state_view
from lander_ros.stamps import stamp_to_seconds
from lander_sim.scenes import load_scene
from lander_tools.fly.plan import Action
from lander_tools.fly.timeline import plan_stops
from lander_tools.scripted import parse_script

from .flightcheck import FLIGHT_TOPICS, check_bag

PERIOD = 0.1  # s: the hover scene's dt at publish_rate 10 Hz, one physics step per control instant
SCRIPT = {
    "name": "timed-demand-steps", "scene": "hover", "speed": 0, "sim": {"publish_rate": 10.0},
    "end": {"time": 12.05},
    "timeline": [{"t": 0, "demand_altitude": 500.0}, {"t": 5.0, "demand_altitude": 502.0},
                 {"t": 10.04, "demand_altitude": 504.0}],
}


def test_every_action_stops_the_sim_at_the_first_control_instant_at_or_after_it():
    stops = plan_stops([Action(1.0, "demand_altitude", 1.0), Action(1.05, "wind", [0, 0, 0]),
                        Action(1.1, "stabiliser", True), Action(0.0, "wind", [0, 0, 0]),
                        Action(3.0, "parachute")], PERIOD, 2.0)
    # 1.0 -> instant 10; 1.05 and 1.1 -> instant 11 (one stop); instant 0 goes before the start;
    # nothing at or after the end, the first instant >= 2.0 s (20), where the sim stops by itself.
    assert [(s.index, [a.kind for a in s.actions]) for s in stops] == [
        (10, ["demand_altitude"]), (11, ["wind", "stabiliser"])]


def test_a_demand_step_at_speed_0_is_in_force_from_the_first_control_instant_at_or_after_it(tmp_path: Path):
    script = parse_script(SCRIPT)
    script.topics = FLIGHT_TOPICS
    result = script.run(record=tmp_path / "bag")
    assert result.exit_code == 0, result.message
    # The end is exact too: the first instant at or after 12.05 s is 12.1 s (121 periods).
    assert math.isclose(result.sim_time, 121 * PERIOD, abs_tol=1e-9)
    bag = check_bag(tmp_path / "bag", result)
    states = bag.messages("/lander/state")
    start = max(i for i, s in enumerate(states) if s.sequence == 1)
    states = states[start:]
    t_last = stamp_to_seconds(states[-1].header.stamp)
    assert math.isclose(t_last, result.sim_time, abs_tol=1e-9), "the sim ran past the end"
    answers = {m.state_sequence: list(m.throttles) for m in bag.messages("/lander/throttle")}

    scene = load_scene("hover")
    wanted = scene_autopilot(scene)
    law = make_controller(wanted.controller, scene.vehicle, **dict(wanted.parameters))
    law.reset()
    # Instants k * 0.1 s: 502 m from instant 50 (t = 5.0), 504 m from instant 101 (t = 10.1 >= 10.04).
    # In the bag each demand message arrived after the /clock of its instant and before the next
    # one (analysis interpolates receive times between clocks, hence within [t_k, t_k + period)).
    from lander_tools.analysis import Flight

    f = Flight.from_bag(bag)
    assert len(f.demand_t) == 3
    for got, t_k in zip(f.demand_t, (0.0, 5.0, 10.1)):
        assert t_k - 1e-9 <= got < t_k + PERIOD, (got, t_k)
    switched = {502.0: 0, 504.0: 0}
    for k, s in enumerate(states):
        demand = 500.0 if k < 50 else 502.0 if k < 101 else 504.0
        st = state_view(s)
        u = law.update(st.t, st, Demand(altitude=demand)).throttles.tolist()
        if s.sequence in answers:
            assert answers[s.sequence] == u, f"state {s.sequence} (t = {st.t:.2f} s) not answered with demand {demand}"
            switched[demand] = switched.get(demand, 0) + 1
    # Both steps were flown (answers before and after each boundary were compared above).
    assert switched[502.0] > 40 and switched[504.0] > 15
