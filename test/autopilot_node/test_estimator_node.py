"""The estimator node (lander_autopilot.estimator_node) as a process beside a real simulator, stepped
tick by tick through its services (no autopilot): one estimate per state with the state's stamp and
sequence; a bad reading refused in one line, counted, and the node flying on; a reset starting the
filter again at the new flight's first state."""
from __future__ import annotations

import math

import pytest
from std_srvs.srv import Trigger

from lander_interfaces.msg import LanderState
from lander_interfaces.srv import Reset, StepSimulation
from lander_ros.flight_span import parse_matched

SCENE = "landing-sensors"
#: Physics steps per control tick of landing-sensors (dt 0.01 s, control at 50 Hz).
STEPS_PER_TICK = 2


@pytest.fixture(scope="module")
def stepped(rig):
    ground = rig.ground
    sim = rig.start("lander_sim.node", "lander_sim",
                    {"scene": SCENE, "start_paused": True, "command_timeout": 0.0})
    est = rig.start("lander_autopilot.estimator_node", "lander_estimator", {"scene": SCENE})
    estimates = ground.record("/lander/estimate/state", LanderState)
    ground.clients["reset"] = ground.node.create_client(Reset, "/lander/reset")
    ground.clients["step"] = ground.node.create_client(StepSimulation, "/lander/step")
    ground.clients["matched"] = ground.node.create_client(Trigger, "/lander_estimator/matched")
    ground.wait_graph({"/lander/sensors/imu": 1}, {"/lander/estimate/state": 1}, services=("reset", "step"))

    def matched() -> bool:  # the estimator's readers have the sim's writers, its writer this reader
        have = parse_matched(ground.call("matched").message)
        return have["/lander/estimate/state"] >= 1 and all(n >= 1 for t, n in have.items() if t.startswith("sub:"))

    ground.wait_for(matched, ground.start_timeout, "the estimator matched both ways")
    return rig, ground, sim, est, estimates


def _reset(ground, estimates) -> None:
    n = len(estimates)
    assert ground.call("reset", Reset.Request()).success
    ground.wait_for(lambda: len(estimates) > n and estimates[-1].sequence == 1, what="the estimate of state 1")


def _step(ground, estimates, ticks: int) -> None:
    want = estimates[-1].sequence + ticks
    req = StepSimulation.Request(steps=ticks * STEPS_PER_TICK)
    assert ground.call("step", req).success
    ground.wait_for(lambda: estimates[-1].sequence >= want, what=f"the estimate of state {want}")


def test_one_estimate_per_state_stamped_as_the_state(stepped) -> None:
    rig, ground, _, _, estimates = stepped
    _reset(ground, estimates)
    start = len(estimates) - 1
    _step(ground, estimates, 25)
    got = estimates[start:]
    assert [m.sequence for m in got] == list(range(1, 27))
    assert [round(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, 9) for m in got] == \
        [round(0.02 * k, 9) for k in range(26)]
    rig.check_alive()


def test_a_bad_reading_is_dropped_in_one_line_counted_and_the_node_flies_on(stepped) -> None:
    """An IMU reading of NaN from a faulty publisher beside the sim, stamped between two steps: no step
    of the flight, whichever order it arrives in among the sim's readings."""
    from sensor_msgs.msg import Imu

    rig, ground, _, est, estimates = stepped
    _reset(ground, estimates)
    pub = ground.node.create_publisher(Imu, "/lander/sensors/imu", 10)
    ground.wait_for(lambda: pub.get_subscription_count() >= 1, ground.start_timeout, "the estimator's IMU reader")
    bad = Imu()
    bad.header.stamp.nanosec = 5_000_000  # t = 0.005 s
    bad.angular_velocity.x = math.nan
    pub.publish(bad)
    _step(ground, estimates, 10)
    ground.wait_for(lambda: "reading dropped (#1): its stamp is no due instant of its sensor" in est.output(),
                    what="the estimator's line dropping the reading")
    last = estimates[-1]
    assert last.sequence == 11 and all(math.isfinite(x) for x in (last.position.x, last.velocity.y, last.altitude))
    rig.check_alive()


def test_a_reset_starts_the_filter_again_at_the_new_flights_first_state(stepped) -> None:
    rig, ground, _, est, estimates = stepped
    _reset(ground, estimates)
    _step(ground, estimates, 5)
    _reset(ground, estimates)
    first = len(estimates) - 1
    _step(ground, estimates, 5)
    assert [m.sequence for m in estimates[first:]] == list(range(1, 7))
    assert "the flight was reset" in est.output()
    rig.check_alive()
