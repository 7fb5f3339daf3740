"""The de-orbit to a landing through the ROS nodes: `flights/deorbit-200km-mpc-to-landing.yaml` (the 200 km orbit to the
500 m hover with `deorbit-mpc`, then a landing on demand) flown by the launcher in lockstep,
recorded, and asserted from its bag with the independent `mcap` + `mcap-ros2-support` reader: the
phases in order on /lander/events, the hover held, a safe touchdown, the MPC's solve times in the
autopilot's last /diagnostics. About 2-4 min of wall time (the entry predictor and the MPC's
reference solve); run with --runslow."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from lander_interfaces.msg import FlightEvent
from lander_sim.physics.constants import MARS_RADIUS
from lander_tools.fly.summary import summary

from .flightcheck import FLIGHT_TOPICS, REPO, mcap_counts

#: Every phase of the de-orbit law, in flight order (lander_autopilot.controllers.deorbit.Phase).
PHASES = ("deorbit-slew", "deorbit-burn", "coast", "entry", "parachute", "powered-descent", "hover", "landing")
DEMAND = 500.0  #: [m] the hover's demand altitude (the flight's timeline)
_MODE = re.compile(r"mode '([^']*)' -> '([^']*)'")


def _t(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def _read(bag: Path) -> dict:
    """What the test needs from the bag, decoded from the schemas embedded in it."""
    from mcap_ros2.reader import read_ros2_messages

    out: dict = {"events": [], "t": [], "r": [], "v": [], "altitude": [], "climb": [], "ground": [], "phase": [],
                 "diagnostics": []}
    for m in read_ros2_messages(str(next(bag.glob("*.mcap")))):
        topic, msg = m.channel.topic, m.ros_msg
        if topic == "/lander/events":
            out["events"].append((_t(msg.header.stamp), int(msg.kind), msg.detail, list(msg.values)))
        elif topic == "/lander/state":
            out["t"].append(_t(msg.header.stamp))
            out["r"].append((msg.position.x, msg.position.y, msg.position.z))
            out["v"].append((msg.velocity.x, msg.velocity.y, msg.velocity.z))
            out["altitude"].append(msg.altitude)
            out["climb"].append(msg.climb_rate)
            out["ground"].append(msg.ground_speed)
            out["phase"].append(msg.phase)
        elif topic == "/diagnostics":
            statuses = {s.name: {kv.key: kv.value for kv in s.values} for s in msg.status}
            out["diagnostics"].append((_t(msg.header.stamp), statuses))
    for k in ("t", "r", "v", "altitude", "climb", "ground", "phase"):
        out[k] = np.array(out[k])
    return out


def _longest_hold(t: np.ndarray, ok: np.ndarray) -> tuple[float, float]:
    """(start, end) [s] of the longest run of consecutive states where ``ok`` holds."""
    best, run_start = (0.0, 0.0), None
    for i, good in enumerate(ok):
        if good and run_start is None:
            run_start = i
        if (not good or i == len(ok) - 1) and run_start is not None:
            end = i if good else i - 1
            if t[end] - t[run_start] > best[1] - best[0]:
                best = (t[run_start], t[end])
            run_start = None
    return best


@pytest.mark.slow
def test_deorbit_mpc_from_200_km_to_a_safe_landing_told_by_its_bag(tmp_path: Path) -> None:
    from lander_tools.scripted import load_script

    script = load_script(REPO / "flights" / "deorbit-200km-mpc-to-landing.yaml")
    script.topics = (*FLIGHT_TOPICS, "/diagnostics")  # the flight's own topics (no odometry, pose, markers)
    bag = tmp_path / "deorbit-mpc"
    result = script.run(record=bag)
    print(summary(result), file=sys.stderr)
    assert result.exit_code == 0 and result.outcome == "landed", summary(result)
    assert result.bag_check.startswith("complete"), result.bag_check
    assert dict(mcap_counts(bag)) == {t: n for t, n in result.counts.items() if n}  # every message decodes
    b = _read(bag)

    # Every phase, once, in order, each a MODE_CHANGED event stamped with the state that began it.
    changes = [(t, *_MODE.search(d).groups()) for t, k, d, _ in b["events"] if k == FlightEvent.MODE_CHANGED]
    assert [(a, z) for _, a, z in changes] == list(zip(PHASES, PHASES[1:])), changes
    at = {z: t for t, _, z in changes}
    assert all(t0 < t1 for t0, t1 in zip(list(at.values()), list(at.values())[1:]))
    assert set(at.values()) <= set(b["t"].tolist())

    # Altitude and speed from the state's position and velocity (world frame `mars`, inertial: the
    # planet does not turn), checked against the simulator's own altitude / climb rate / ground speed.
    h = np.linalg.norm(b["r"], axis=1) - MARS_RADIUS
    speed = np.linalg.norm(b["v"], axis=1)
    assert np.abs(h - b["altitude"]).max() < 1e-3
    assert np.abs(speed - np.hypot(b["climb"], b["ground"])).max() < 1e-6
    # The hover held within 2 m and 0.2 m/s of the demand for 30 s, in the hover phase (before `landing`).
    hovering = (b["t"] >= at["hover"]) & (b["t"] < at["landing"])
    t0, t1 = _longest_hold(b["t"], hovering & (np.abs(h - DEMAND) < 2.0) & (speed < 0.2))
    assert t1 - t0 >= 30.0, (t0, t1)
    held = (b["t"] >= t0) & (b["t"] <= t1)

    # Touchdown: the sim's LANDED event (safe), its figures, and the last flying state's velocity.
    landed = [(t, vals) for t, k, _, vals in b["events"] if k == FlightEvent.LANDED]
    assert len(landed) == 1 and not [e for e in b["events"] if e[1] in (FlightEvent.CRASHED, FlightEvent.HARD_LANDING)]
    t_impact, descent, ground = landed[0][1][:3]
    assert descent < 1.0 and ground < 1.0
    flying = np.flatnonzero(b["phase"] == 0)[-1]
    assert -b["climb"][flying] < 1.0 and b["ground"][flying] < 1.0

    # The autopilot's last report: the MPC's solve times, p99 under the control period.
    reports = [(t, s) for t, s in b["diagnostics"] if "autopilot: deorbit-mpc" in s]
    assert reports, "no /diagnostics of the autopilot's controller in the bag"
    t_last, last = reports[-1]
    loop, mpc = last["autopilot: control"], last["autopilot: deorbit-mpc"]
    period = float(loop["control_period_s"])
    assert period == pytest.approx(0.1, abs=1e-9)  # the flight's publish_rate 10 Hz, dt 0.1 s
    assert float(mpc["mpc_solves"]) > 0 and float(mpc["mpc_failures"]) == 0
    assert float(mpc["mpc_solve_time_p99"]) < period
    assert float(mpc["mpc_solve_time_median"]) <= float(mpc["mpc_solve_time_p99"]) <= float(mpc["mpc_solve_time_max"])
    print(f"deorbit-200km-mpc-to-landing: wall {result.wall_time:.1f} s; phases "
          + ", ".join(f"{z} {t:.1f}" for t, _, z in changes)
          + f"; held {t0:.1f}-{t1:.1f} s, max |h - {DEMAND:g}| {np.abs(h[held] - DEMAND).max():.3f} m, "
          f"max speed {speed[held].max():.3f} m/s; touchdown {t_impact:.3f} s, {descent:.3f} m/s, {ground:.3f} m/s; "
          f"last report t = {t_last:.1f} s: MPC {mpc['mpc_solves']} solves, median {mpc['mpc_solve_time_median']} s, "
          f"p99 {mpc['mpc_solve_time_p99']} s, max {mpc['mpc_solve_time_max']} s, reference "
          f"{mpc['mpc_reference_time']} s; loop period {period} s, compute median {loop['compute_time_median_s']} s, "
          f"p99 {loop['compute_time_p99_s']} s, max {loop['compute_time_max_s']} s, overruns {loop['overruns']} "
          f"of {loop['periods']}", file=sys.stderr)
