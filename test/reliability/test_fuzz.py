"""Bad input at volume on the live nodes: random and adversarial messages on every subscribed topic,
random arguments to the services and parameters. No node dies, every rejection is counted (exactly:
the test classifies each input itself from the documented rules), and rejected input leaves the
state unchanged, bit for bit (the sim is paused, so nothing else can change it).

Hypothesis draws the inputs with a fixed seed and a bounded number of examples in CI
(``conftest.PROFILE``): a failure reproduces by re-running.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rosutil

from .conftest import PROFILE
from .stack import REPLY_TIMEOUT, START_TIMEOUT, Stack, Watch

SCENE = "hover-canted"
N_THRUSTERS = 4

floats = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [0.0, 1.0, -0.0, 1.0 + 2**-52, -1e-300, 0.5, math.nan, math.inf, -math.inf, 1e308])
throttle_msgs = st.tuples(
    st.lists(floats | st.floats(0.0, 1.0), min_size=0, max_size=7),
    st.integers(0, 2**64 - 1),
)
wind_msgs = st.tuples(st.sampled_from(["", "mars", "base_link", "MARS", "mars ", "\u00e9"]) | st.text(max_size=20),
                      st.tuples(floats, floats, floats))


def throttle_ok(values: list[float]) -> bool:
    """docs/sim_node.md: one throttle per thruster, each in [0, 1]; NaN/inf refused, never clamped."""
    return len(values) == N_THRUSTERS and all(0.0 <= v <= 1.0 for v in values)


def wind_ok(frame: str, v: tuple[float, float, float]) -> bool:
    return frame in ("", "mars") and all(math.isfinite(x) for x in v)


def state_fields(msg) -> tuple:
    """Everything in a state message but its sequence number (republished with a new one)."""
    from rclpy.serialization import serialize_message

    seq, msg.sequence = msg.sequence, 0
    try:
        return serialize_message(msg)
    finally:
        msg.sequence = seq


@pytest.fixture
def paused_sim(stack: Stack, watch: Watch) -> Watch:
    stack.sim(scene=SCENE, start_paused=True, diagnostics_rate=20.0, command_timeout=0.0)
    watch.wait_graph({"/lander/throttle": 1, "/lander/wind": 1}, {"/lander/state": 1},
                     services=("pause", "step", "load_scene"))
    watch.latest_diag()
    for _ in range(20):  # until the sim's state publisher has matched our subscription
        n = len(watch.states)
        assert watch.call("step", _step1()).success
        try:
            watch.wait_for(lambda: len(watch.states) > n, 1.0, "a state")
            return watch
        except TimeoutError:
            continue
    raise AssertionError("no state from the paused sim after 20 steps")


def _step1():
    from lander_interfaces.srv import StepSimulation

    return StepSimulation.Request(steps=1)


def _counts(watch: Watch) -> tuple[int, int]:
    d = watch.latest_diag()
    return int(d["rejected_total"]), int(d["commands_accepted"])


def _reset(watch: Watch) -> None:
    assert watch.call("reset").success


def _stepped_state(watch: Watch):
    """The state one physics step on (the sim stays paused). From a reset this is bit-exactly
    the same state every time unless an accepted input changed the dynamics: so comparing it
    shows whether rejected input touched anything (throttles, wind)."""
    from lander_ros.stamps import sim_time_to_ns

    n = len(watch.states)
    res = watch.call("step", _step1())
    assert res.success
    # The state of the step's instant, found by its stamp: the reset's state 1 (t = 0) can arrive
    # after the step was asked for, and taking the newest state then compared it (a run saw the
    # stamps differ: bytes 8-11 of the serialised state).
    ns = sim_time_to_ns(res.sim_time)

    def stepped() -> list:
        return [m for m in watch.states[n:] if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == ns]

    watch.wait_for(lambda: bool(stepped()), what="the state after one step")
    return stepped()[0]


def test_fuzzed_throttle_and_wind_messages_are_counted_and_rejected_ones_change_nothing(
        stack: Stack, paused_sim: Watch) -> None:
    from geometry_msgs.msg import Vector3Stamped

    from lander_interfaces.msg import FlightEvent, ThrottleCommand

    watch = paused_sim

    _reset(watch)
    before = _stepped_state(watch)

    @settings(PROFILE)
    @given(st.lists(st.one_of(throttle_msgs.map(lambda m: ("throttle", m)), wind_msgs.map(lambda m: ("wind", m))),
                    min_size=1, max_size=30))
    def check(batch):
        _reset(watch)
        rejected0, accepted0 = _counts(watch)
        n_events = len(watch.events)
        bad, good_throttles, last_good = 0, 0, None
        for kind, m in batch:
            if kind == "throttle":
                values, seq = m
                watch.pub["throttle"].publish(ThrottleCommand(state_sequence=seq, throttles=[float(v) for v in values]))
                if throttle_ok(values):
                    good_throttles, last_good = good_throttles + 1, [float(v) for v in values]
                else:
                    bad += 1
            else:
                frame, v = m
                msg = Vector3Stamped()
                msg.header.frame_id = frame
                msg.vector.x, msg.vector.y, msg.vector.z = (float(x) for x in v)
                watch.pub["wind"].publish(msg)
                bad += not wind_ok(frame, v)
        # One input queue per topic, processed in order: wait until every input is accounted for.
        watch.wait_for(lambda: _counts(watch) == (rejected0 + bad, accepted0 + good_throttles), START_TIMEOUT,
                       f"{bad} rejections and {good_throttles} acceptances counted")
        stack.check_alive()
        after = _stepped_state(watch)
        if any(k == "wind" and wind_ok(*m) for k, m in batch):
            pass  # an accepted wind changes the step: only the counts are checked
        elif last_good is None:
            assert state_fields(after) == state_fields(before)  # rejected input changed nothing
        else:
            assert list(after.throttles) == last_good  # the accepted command, exactly (no clamping)
        watch.wait_for(lambda: sum(e.kind == FlightEvent.INPUT_REJECTED for e in watch.events[n_events:]) >= bad,
                       what="one INPUT_REJECTED event per rejection")
        assert sum(e.kind == FlightEvent.INPUT_REJECTED for e in watch.events[n_events:]) == bad

    check()


def test_fuzzed_service_arguments_are_refused_counted_and_change_nothing(stack: Stack, paused_sim: Watch) -> None:
    from lander_interfaces.srv import LoadScene, RunUntil, StepSimulation
    from lander_sim.scenes import list_scenes

    watch = paused_sim
    known = {s.name for s in list_scenes()} | {a for s in list_scenes() for a in s.aliases}
    t_now = 0.0
    bad_scene = st.text(max_size=40).filter(lambda s: s.strip() not in known and s.strip() != "") | st.sampled_from(
        ["", "/etc/passwd", "/dev/null", "../../../../etc/shadow", "hover\x00", "h" * 5000, "/nonexistent.yaml"])
    bad_until = st.sampled_from([math.nan, math.inf, -math.inf, -1.0, t_now, -1e308]) | st.floats(max_value=t_now)
    calls = st.one_of(bad_scene.map(lambda s: ("load_scene", LoadScene.Request(scene=s))),
                      bad_until.map(lambda x: ("run_until", RunUntil.Request(sim_time=x))),
                      st.just(("step", StepSimulation.Request(steps=0))))

    _reset(watch)
    before = _stepped_state(watch)

    @settings(PROFILE)
    @given(st.lists(calls, min_size=1, max_size=5))
    def check(batch):
        _reset(watch)
        rejected0, accepted0 = _counts(watch)
        for name, req in batch:
            res = watch.call(name, req)
            assert res.success is False and res.message, (name, req)
        watch.wait_for(lambda: _counts(watch)[0] == rejected0 + len(batch), what="every refusal counted")
        stack.check_alive()
        assert state_fields(_stepped_state(watch)) == state_fields(before)

    check()


def test_refused_sim_parameter_changes_are_counted(stack: Stack, paused_sim: Watch) -> None:
    """A refused parameter is bad input like any other: counted in rejected_total and announced by
    one INPUT_REJECTED event (docs/sim_node.md), whether our validation refused it (speed < 0) or
    rclpy's own checks did (a read-only parameter, an undeclared name)."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    from lander_interfaces.msg import FlightEvent

    watch = paused_sim
    refused = [("speed", ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)),
               ("scene", ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="hover")),
               ("no_such_parameter", ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True))]
    for name, value in refused:
        rejected0, _ = _counts(watch)
        n_events = len(watch.events)
        res = watch.call("sim_set_parameters", SetParameters.Request(parameters=[Parameter(name=name, value=value)]))
        assert not res.results[0].successful and res.results[0].reason, name
        # Exactly one more: the counter is read from diagnostics published at 20 Hz.
        watch.wait_for(lambda: _counts(watch)[0] == rejected0 + 1, REPLY_TIMEOUT, f"the refusal of {name} counted")
        watch.wait_for(lambda: any(e.kind == FlightEvent.INPUT_REJECTED for e in watch.events[n_events:]),
                       what=f"INPUT_REJECTED for {name}")
        event = next(e for e in watch.events[n_events:] if e.kind == FlightEvent.INPUT_REJECTED)
        assert event.detail.startswith("parameter."), event.detail
    assert watch.parameter("sim", "speed") == 1.0  # the refused value left the parameter as it was


param_values = st.one_of(st.booleans(), st.integers(-2**63, 2**63 - 1), floats, st.text(max_size=30),
                         st.lists(st.floats(allow_nan=False), max_size=3))


def test_fuzzed_parameters_never_kill_the_nodes_and_refused_ones_change_nothing(stack: Stack, paused_sim: Watch) -> None:
    """Random values (any type) for every declared parameter of the sim, and random names."""
    from rcl_interfaces.msg import Parameter
    from rcl_interfaces.srv import SetParameters

    from lander_sim.ros.config import PARAMETERS

    watch = paused_sim
    names = [p.name for p in PARAMETERS]

    @settings(PROFILE)
    @given(st.sampled_from(names) | st.text(min_size=1, max_size=20), param_values)
    def check(name, value):
        old = watch.parameter("sim", name) if name in names else None
        res = watch.call("sim_set_parameters", SetParameters.Request(
            parameters=[Parameter(name=name, value=rosutil.param_value(value))])).results[0]
        stack.check_alive()
        if not res.successful:
            assert res.reason
            if name in names:
                now = watch.parameter("sim", name)
                assert now == old or (isinstance(old, float) and math.isnan(old) and math.isnan(now))
        # Keep the sim paused and usable for the next example.
        if name in names and res.successful:
            watch.call("sim_set_parameters", SetParameters.Request(parameters=[Parameter(name=name, value=rosutil.param_value(old))]))

    check()
    assert _stepped_state(watch) is not None  # still answering


# --- the autopilot -----------------------------------------------------------------------------


@pytest.fixture
def lone_autopilot(stack: Stack, watch: Watch) -> Watch:
    """The autopilot with the test playing the simulator (no sim running)."""
    stack.autopilot(scene=SCENE, state_timeout=1000.0)
    watch.wait_graph({"/lander/state": 2, "/lander/demand_altitude": 1}, {"/lander/throttle": 1},
                     services=("switch_controller", "ap_get_parameters"))
    return watch


def _base_state():
    from lander_interfaces.msg import LanderState
    from lander_sim.ros import convert
    from lander_sim.ros.sim_adapter import build_simulation

    msg = LanderState()
    convert.fill_state(msg, 1, build_simulation(SCENE).readout())
    return msg


BREAKS = ("position.x", "velocity.z", "orientation.w", "angular_velocity.y", "fuel_mass", "euler_zxz",
          "zero_quaternion", "thruster_count")


def _break(msg, how: str, value: float) -> None:
    if how == "zero_quaternion":
        msg.orientation.x = msg.orientation.y = msg.orientation.z = msg.orientation.w = 0.0
    elif how == "thruster_count":
        msg.throttles = [0.0] * (N_THRUSTERS + 1)
    elif how == "euler_zxz":
        msg.euler_zxz[1] = value
    else:
        obj, _, field = how.rpartition(".")
        setattr(getattr(msg, obj) if obj else msg, field, value)


def _status_count(watch: Watch) -> int:
    return watch.statuses[-1].rejected if watch.statuses else 0


def test_fuzzed_states_demands_and_switches_to_the_autopilot(stack: Stack, lone_autopilot: Watch) -> None:
    from std_msgs.msg import Float64

    from lander_autopilot.controllers import available_controllers
    from lander_interfaces.srv import SwitchController

    watch = lone_autopilot
    base = _base_state()
    seq = [1]
    active = watch.call("switch_controller", SwitchController.Request(controller="combined-quaternion")).active_controller
    controllers = set(available_controllers())
    bad_number = st.sampled_from([math.nan, math.inf, -math.inf])
    inputs = st.one_of(
        st.tuples(st.just("state"), st.sampled_from(BREAKS + ("valid",)), bad_number),
        st.tuples(st.just("demand"), floats, st.none()),
        st.tuples(st.just("switch"), st.text(max_size=20).filter(lambda s: s not in controllers), st.text(max_size=40)),
    )

    @settings(PROFILE)
    @given(st.lists(inputs, min_size=1, max_size=8))
    def check(batch):
        for kind, a, b in batch:
            n_status, n_thr = len(watch.statuses), len(watch.throttles)
            rejected0 = _status_count(watch)
            if kind == "state":
                msg = _base_state() if a == "valid" else base
                seq[0] += 1
                msg.sequence = seq[0]
                if a != "valid":
                    msg = _base_state()
                    msg.sequence = seq[0]
                    _break(msg, a, b)
                watch.pub["state"].publish(msg)
                # Every state gets exactly one status: with the command, or with the refusal.
                watch.wait_for(lambda: len(watch.statuses) > n_status, what=f"the status after state {a}")
                if a == "valid":
                    watch.wait_for(lambda: len(watch.throttles) > n_thr, what="the command")
                    cmd = watch.throttles[-1]
                    assert cmd.state_sequence == seq[0] and len(cmd.throttles) == N_THRUSTERS
                    assert all(0.0 <= x <= 1.0 for x in cmd.throttles)
                    assert watch.statuses[-1].rejected == rejected0
                else:
                    assert watch.statuses[-1].rejected == rejected0 + 1
                    watch.drain()
                    assert len(watch.throttles) == n_thr, "a command for a refused state"
            elif kind == "demand":
                old = watch.parameter("ap", "demand_altitude")
                watch.pub["demand"].publish(Float64(data=float(a)))
                ok = math.isfinite(a) and a >= 0.0
                if ok:
                    watch.wait_for(lambda: watch.parameter("ap", "demand_altitude") == float(a), what="demand applied")
                else:
                    watch.wait_for(lambda: len(watch.statuses) > n_status, what="the refusal's status")
                    assert watch.statuses[-1].rejected == rejected0 + 1
                    assert watch.parameter("ap", "demand_altitude") == old
            else:
                res = watch.call("switch_controller", SwitchController.Request(controller=a, parameters_yaml=b))
                assert res.success is False and res.message and res.active_controller == active
                watch.wait_for(lambda: _status_count(watch) == rejected0 + 1, what="the refused switch counted")
            stack.check_alive()

    check()
