"""The ground-speed law over the real middleware: /lander/demand_velocity, its refusals, the status.

Simulator and autopilot nodes as processes, lockstep at full speed (as test_autopilot_flights.py);
scene ``ground-speed`` (500 m hover moving east at 50 m/s, canted thrusters, no stabiliser).
"""
from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import Vector3Stamped

from lander_autopilot.controllers import Demand, make_controller
from lander_autopilot.design.translational import LOCAL_FRAME, local_frame
from lander_autopilot.ros.convert import state_view
from lander_interfaces.msg import FlightEvent
from lander_sim.scenes import load_scene

from .ground import seconds
from .test_autopilot_flights import answers, fly_until, start_flight, start_lockstep_flight

SCENE = "ground-speed"


@pytest.fixture(scope="module")
def flight(rig):
    rig.ground.pub_velocity = rig.ground.node.create_publisher(Vector3Stamped, "/lander/demand_velocity", 10)
    return start_lockstep_flight(rig, SCENE, "ground-speed", subscribers={"/lander/demand_velocity": 1})


def velocity_msg(x: float, y: float, z: float = 0.0, frame: str = LOCAL_FRAME) -> Vector3Stamped:
    m = Vector3Stamped()
    m.header.frame_id = frame
    m.vector.x, m.vector.y, m.vector.z = float(x), float(y), float(z)
    return m


def test_demand_velocity_mid_flight_changes_ground_speed_as_designed(flight):
    """Every answer is the core law's (same demand from the same state on), and the lander then
    flies the demanded 4 m/s north within 0.05 m/s."""
    g = flight.ground
    mark = start_flight(flight, "ground-speed")
    g.wait_for(lambda: seconds(g.states[-1].header.stamp) >= 30.0, 120.0, "30 s of flight")
    g.pub_velocity.publish(velocity_msg(0.0, 4.0))
    g.wait_for(lambda: any(s.velocity_demanded for s in g.statuses[mark.statuses:]), what="the demand in the status")
    t_demand = seconds(next(s for s in g.statuses[mark.statuses:] if s.velocity_demanded).header.stamp)
    states = fly_until(flight, t_demand + 30.0, mark)

    law = make_controller("ground-speed", load_scene(SCENE).vehicle)
    pairs = answers(flight, states, mark)
    for s, u in pairs:
        st = state_view(s)
        d = Demand(altitude=500.0, velocity=(0.0, 4.0) if st.t >= t_demand - 1e-9 else None)
        assert law.update(st.t, st, d).throttles.tolist() == u, f"state {s.sequence} at t = {st.t} s"
    assert 25.0 < t_demand < 40.0  # published mid-flight
    last = state_view(states[-1])
    v = local_frame(last.r_W) @ last.v_W
    assert v[0] == pytest.approx(0.0, abs=0.05) and v[1] == pytest.approx(4.0, abs=0.05)
    assert abs(states[-1].altitude - 500.0) < 5.0
    st = g.statuses[-1]
    assert st.velocity_demanded and (st.demand_velocity.x, st.demand_velocity.y, st.demand_velocity.z) == (0.0, 4.0, 0.0)


@pytest.mark.parametrize("bad, why", [
    (velocity_msg(1.0, 0.0, frame="mars"), "frame 'mars'"),
    (velocity_msg(1.0, 0.0, frame=""), "frame ''"),
    (velocity_msg(math.nan, 0.0), "finite"),
    (velocity_msg(math.inf, 0.0), "finite"),
    (velocity_msg(500.0, 0.0), "absurd"),
    (velocity_msg(1.0, 0.0, z=1.0), "z = 1.0"),
])
def test_bad_demand_velocity_is_refused_counted_and_announced(flight, bad, why):
    g = flight.ground
    g.drain()
    before = g.statuses[-1].rejected if g.statuses else 0
    demand_before = g.statuses[-1].velocity_demanded if g.statuses else False
    n_events = len(g.events)
    g.pub_velocity.publish(bad)
    g.wait_for(lambda: g.statuses and g.statuses[-1].rejected == before + 1, what="the refusal counted")
    st = g.statuses[-1]
    assert why in st.last_error and "demand_velocity" in st.last_error
    assert st.velocity_demanded == demand_before  # the demand in force is untouched
    g.wait_for(lambda: any(e.kind == FlightEvent.INPUT_REJECTED for e in g.events[n_events:]), what="INPUT_REJECTED")
    flight.check_alive()
