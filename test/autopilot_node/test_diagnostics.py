"""The autopilot's /diagnostics: the control loop's figures (lander_autopilot.ros.loop_stats) and,
through the real node in a lockstep flight, the reports on the sim clock (docs/autopilot_node.md)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from std_srvs.srv import Trigger

from lander_autopilot.ros.loop_stats import (
    OK,
    WARN,
    LoopStats,
    ReportClock,
    control_status,
    controller_status,
)
from lander_interfaces.msg import FlightEvent

from .ground import seconds
from .test_autopilot_flights import DT_CONTROL, fly_until, start_flight, start_lockstep_flight

# --- plain Python: the statistics ----------------------------------------------------------------


def test_loop_stats_give_the_period_percentiles_max_and_overruns():
    s = LoopStats(window=100)
    computes = [0.001 * (i % 10 + 1) for i in range(150)]  # 1..10 ms, repeating
    computes[7] = 0.25  # one period overrun (> 0.1 s), before the window's last 100
    for k, c in enumerate(computes):
        s.add(round(k * 0.1, 9) + 4519.0, c)  # stamps far from 0: the period is still 0.1 exactly
    got = s.summary()
    assert got.period == 0.1
    assert got.periods == 150 and got.window == 100
    last = np.array(computes[-100:])
    assert got.median == pytest.approx(np.percentile(last, 50)) and got.p99 == pytest.approx(np.percentile(last, 99))
    assert got.max == 0.25 and got.overruns == 1
    assert got.total == pytest.approx(sum(computes)) and got.mean == pytest.approx(sum(computes) / 150)


def test_the_period_is_the_smallest_step_a_missed_state_or_a_repeated_instant_does_not_change_it():
    s = LoopStats()
    s.add(0.0, 0.3)  # before the period is known: classified once it is
    s.add(0.2, 0.001)  # a state missed: 0.2 s
    assert s.summary().period == 0.2 and s.summary().overruns == 1
    s.add(0.3, 0.15)
    s.add(0.3, 0.001)  # a pause re-publishes the instant: no step of 0
    got = s.summary()
    assert got.period == pytest.approx(0.1) and got.periods == 4
    # 0.15 s is over the period known when it came (0.1 s), 0.3 s over the first (0.2 s)
    assert got.overruns == 2


def test_reset_forgets_everything_and_a_swap_keeps_only_the_period():
    s = LoopStats()
    for k in range(5):
        s.add(k * 0.1, 0.2)
    s.reset(keep_period=True)
    assert s.summary().period == pytest.approx(0.1) and s.summary().periods == 0 and s.summary().overruns == 0
    s.add(1.0, 0.2)
    assert s.summary().overruns == 1  # classified against the kept period at once
    s.reset()
    got = s.summary()
    assert math.isnan(got.period) and math.isnan(got.median) and math.isnan(got.max) and got.periods == 0


def test_reports_fall_on_each_second_of_sim_time_whatever_the_step():
    clock = ReportClock(1.0)
    times = [round(k * 0.3, 9) for k in range(15)]  # 0, 0.3, ..., 4.2
    assert [t for t in times if clock.due(t)] == [0.0, 1.2, 2.1, 3.0, 4.2]
    clock.reset()
    assert clock.due(0.0)


def test_status_levels_and_values():
    s = LoopStats()
    level, message, values = control_status(s.summary(), "landing", "")
    assert level == OK and "no state" in message and values["periods"] == "0" and values["control_period_s"] == "nan"
    for k in range(10):
        s.add(k * 0.1, 0.01)
    level, message, values = control_status(s.summary(), "landing", "coast")
    assert level == OK and values["controller"] == "landing" and values["mode"] == "coast"
    assert float(values["control_period_s"]) == 0.1 and float(values["compute_time_median_s"]) == 0.01
    assert values["overruns"] == "0" and values["periods"] == "10" and values["window_periods"] == "10"
    s.add(1.0, 0.5)
    s.add(1.1, 0.5)
    level, message, _ = control_status(s.summary(), "landing", "coast")
    assert level == WARN and "exceeds the control period" in message
    level, _, values = controller_status({"mpc_solves": 93.0, "mpc_solve_time_p99": 0.0252})
    assert level == OK and values == {"mpc_solves": "93", "mpc_solve_time_p99": "0.0252"}
    level, message, values = controller_status(None, "diagnostics() failed: RuntimeError: x")
    assert level == 2 and "RuntimeError" in message and values == {}


# --- through the node ------------------------------------------------------------------------------

SCENE = "landing-hover"  # 500 m at rest: the landing law coasts, then brakes (a mode change)
CONTROL = "autopilot: control"


@pytest.fixture(scope="module")
def flight(rig):
    reports: list[DiagnosticArray] = []
    rig.ground.node.create_subscription(
        DiagnosticArray, "/diagnostics",
        lambda m: reports.append(m) if any(s.name == CONTROL for s in m.status) else None, 1000)
    rig.reports = reports
    return start_lockstep_flight(rig, SCENE, "landing")


def _values(status) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def test_the_node_reports_its_control_loop_each_second_and_at_each_mode_change(flight):
    g, reports = flight.ground, flight.reports
    n0 = len(reports)
    mark = start_flight(flight, "landing")
    first = _reset_report(flight, n0)

    def changed() -> list:
        return [e for e in g.events[mark.events:] if e.kind == FlightEvent.MODE_CHANGED]

    g.wait_for(changed, 60.0, "the landing law's first mode change")
    t_change = seconds(changed()[0].header.stamp)
    states = fly_until(flight, math.floor(t_change) + 1.0, mark)
    t_last = seconds(states[-1].header.stamp)
    g.wait_for(lambda: reports and seconds(reports[-1].header.stamp) >= math.floor(t_last + 1e-9), 10.0,
               "the report of the last whole second")
    mine = reports[first:]
    stamps = [seconds(r.header.stamp) for r in mine]
    # The sim clock, not the wall: every whole second from the reset's t = 0, and the mode change.
    expected = sorted({float(k) for k in range(int(math.floor(t_last + 1e-9)) + 1)} | {t_change})
    assert stamps == pytest.approx(expected, abs=1e-9)

    for r, t in zip(mine, stamps):
        assert len(r.status) == 1  # `landing` has no diagnostics() of its own
        st = r.status[0]
        v = _values(st)
        assert st.name == CONTROL and st.hardware_id == "/autopilot" and v["controller"] == "landing"
        # one period per state answered since the reset (lockstep: every state, t = 0 included)
        assert int(v["periods"]) == round(t / DT_CONTROL) + 1
        if t == 0.0:
            assert v["control_period_s"] == "nan"  # one state: no period yet
            continue
        period, med, p99, worst = (float(v[k]) for k in ("control_period_s", "compute_time_median_s",
                                                         "compute_time_p99_s", "compute_time_max_s"))
        assert period == pytest.approx(DT_CONTROL, abs=1e-9)  # the simulator's control period
        assert 0.0 < med <= p99 <= worst
        assert 0 <= int(v["overruns"]) <= int(v["periods"])
        assert int(v["window_periods"]) == min(int(v["periods"]), 1000)
        assert st.level == bytes([WARN if p99 > period else OK])
    at_change = mine[stamps.index(pytest.approx(t_change, abs=1e-9))]
    assert _values(at_change.status[0])["mode"] == changed()[0].detail.split("-> ")[-1].strip("'")

    # A reset is a new flight: its figures start again from its first state.
    n1 = len(reports)
    start_flight(flight, "landing")
    _reset_report(flight, n1)  # a report at the new t = 0 counting one period: that state's
    assert g.call(g.pause_sim, Trigger.Request()).success


def _reset_report(rig, after: int) -> int:
    """Index of the report the autopilot made answering the reset's state 1 (t = 0, one period):
    the last such report after index ``after`` (the flight is running: later ones are at t > 0)."""
    def at_zero() -> list[int]:
        return [i for i in range(after, len(rig.reports)) if seconds(rig.reports[i].header.stamp) == 0.0
                and _values(rig.reports[i].status[0])["periods"] == "1"]

    rig.ground.wait_for(at_zero, 10.0, "the autopilot's report at the reset's t = 0")
    return at_zero()[-1]
