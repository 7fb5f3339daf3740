"""A controller swap never stalls the control loop: simulator in lockstep with a short lockstep
timeout, autopilot starting on a law that needs no python-control, swapped mid-flight to one
designed with python-control (LQR). The build runs off the control thread while the old law keeps
answering, so the simulator never waits out its timeout and never holds a stale command."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray

from lander_autopilot.controllers import make_controller
from lander_interfaces.msg import FlightEvent
from lander_sim.scenes import load_scene

from .ground import START_TIMEOUT, seconds, wait_for_graph
from .test_autopilot_flights import SCENE, answers, expected, fly_until, start_flight, switch_mid_flight

#: Short, so a switch that blocks the control thread (first `import control` ~3 s, a design
#: ~50 ms, both measured on this machine) would be counted; one answer normally takes ~1 ms.
LOCKSTEP_TIMEOUT = 0.3


def test_a_swap_to_a_designed_controller_keeps_lockstep_fed_and_falls_on_one_boundary(rig):
    rig.start("lander_sim.node", "sim", {
        "scene": SCENE, "lockstep": True, "speed": 0.0, "start_paused": True, "publish_rate": 10.0,
        "lockstep_timeout": LOCKSTEP_TIMEOUT, "diagnostics_rate": 20.0,
    })
    rig.start("lander_autopilot.node", "autopilot", {"scene": SCENE, "controller": "baseline"})
    g = rig.ground
    diags: list[dict[str, str]] = []
    g.node.create_subscription(DiagnosticArray, "/diagnostics",
                               lambda m: diags.extend({kv.key: kv.value for kv in s.values} for s in m.status
                                                      if s.name.startswith("lander_sim")), 100)
    wait_for_graph(g, subscribers={"/lander/state": 2, "/lander/throttle": 2},
                   publishers={"/lander/throttle": 1, "/lander/state": 1})
    g.wait_for(g.switch.service_is_ready, START_TIMEOUT, "autopilot's switch service")
    vehicle = load_scene(SCENE).vehicle
    old, new = make_controller("baseline", vehicle), make_controller("lqr", vehicle)

    mark = start_flight(rig, "baseline")
    g.wait_for(lambda: diags and int(diags[-1]["ticks"]) > 0, 10.0, "diagnostics of the running sim")
    before = diags[-1]
    g.wait_for(lambda: seconds(g.states[-1].header.stamp) >= 3.0, 60.0, "3 s of flight")
    t_switch = switch_mid_flight(rig, "lqr", mark)
    states = fly_until(rig, t_switch + 3.0, mark)
    n = len(diags)
    g.wait_for(lambda: len(diags) > n + 1, 10.0, "diagnostics after the pause")
    after = diags[-1]

    # The loop never waited out its timeout and never ran on a stale command.
    assert int(after["lockstep_timeouts"]) == int(before["lockstep_timeouts"]), "a lockstep timeout was counted"
    assert int(after["stale_commands"]) == int(before["stale_commands"])
    assert not [e for e in g.events[mark.events:] if e.kind == FlightEvent.COMMAND_STALE]
    # Exactly one boundary: every answer before it by the old law, every one from it by the new.
    pairs = answers(rig, states, mark)
    k = next(i for i, (s, u) in enumerate(pairs) if u != expected(old, s))
    assert 25 < k < len(pairs) - 25, "the swap did not happen mid-flight"
    assert all(u == expected(old, s) for s, u in pairs[:k])
    assert all(u == expected(new, s) for s, u in pairs[k:])
    switched = [e for e in g.events[mark.events:] if e.kind == FlightEvent.CONTROLLER_SWITCHED]
    assert len(switched) == 1 and switched[0].values[0] == pairs[k - 1][0].sequence
    assert g.statuses[-1].state_ok  # states kept arriving throughout
