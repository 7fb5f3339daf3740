"""Ground speed and landing as scripted flights with the real sim and autopilot nodes, asserted from
their bags; and a landing flown through the nodes against the same case flown core-only."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lander_autopilot.design.translational import local_frame
from lander_tools.analysis import EV_LANDED, Flight, metrics
from lander_tools.fly.summary import summary
from lander_tools.sweep.ros_path import through_ros
from lander_tools.sweep.spec import load_spec

from .flightcheck import REPO, check_bag, fly_shipped

EV_PARACHUTE_DEPLOYED, EV_LANDING_UNREACHABLE, EV_MODE_CHANGED = 4, 10, 11  # FlightEvent.msg


def ground_speed(f: Flight) -> np.ndarray:
    return np.array([np.hypot(*(local_frame(r) @ v)[:2]) for r, v in zip(f.r_W, f.v_W)])


def touchdown(f: Flight) -> list[float]:
    """The LANDED event's values: t_impact [s], descent rate [m/s], ground speed [m/s], tilt [deg], fuel [kg]."""
    landed = [e for e in f.events if e[1] == EV_LANDED]
    assert len(landed) == 1, f.events
    return landed[0][3]


def test_ground_speed_step_at_500_m(tmp_path: Path) -> None:
    result, bag = fly_shipped("ground-speed-step", tmp_path)
    f = Flight.from_bag(check_bag(bag, result))
    gs = ground_speed(f)
    assert gs[0] == pytest.approx(50.0)
    # Acceptance: below 0.2 m/s within 30 s and for good; altitude within 5 m of 500 m throughout.
    t_settled = f.t[np.flatnonzero(gs >= 0.2)[-1] + 1]
    assert t_settled < 30.0
    assert np.abs(f.altitude - 500.0).max() < 5.0
    assert f.t[-1] == pytest.approx(40.0)


def test_landing_from_hover(tmp_path: Path) -> None:
    result, bag = fly_shipped("landing-from-hover", tmp_path)
    b = check_bag(bag, result)
    f = Flight.from_bag(b)
    _, rate, speed, tilt_deg, fuel = touchdown(f)
    assert rate < 0.5 and speed < 0.2 and tilt_deg < 5.0
    assert fuel == pytest.approx(f.fuel[-1], abs=0.05)
    modes = [e[2].split("mode ")[-1] for e in f.events if e[1] == EV_MODE_CHANGED]
    assert modes == ["'coast' -> 'braking'", "'braking' -> 'flare'"]
    assert not [e for e in f.events if e[1] in (EV_PARACHUTE_DEPLOYED, EV_LANDING_UNREACHABLE)]
    st = b.series("/autopilot/status")
    # The autopilot's start-up reports (sent by its watchdog before its first state, so only when
    # start-up is slow: wall clock) come before the controller has run and carry no mode.
    flown = st["steps"] > 0
    assert list(dict.fromkeys(st["mode"][flown])) == ["coast", "braking", "flare"]
    # The flight summary and `lander analyse` give the same figures, each with its unit.
    line = next(x for x in summary(result).splitlines() if "touchdown" in x)
    assert line.startswith("  touchdown at t = ") and f"descent rate {rate:.2f} m/s" in line
    assert line.endswith("safe (against the scene's touchdown limits)")
    assert f"tilt {tilt_deg:.2f} deg" in line and f"fuel left {fuel:.2f} kg" in line
    m = metrics(f)
    assert (m.touchdown_class, m.touchdown_descent_rate, m.touchdown_ground_speed, m.touchdown_tilt,
            m.touchdown_fuel_left) == ("safe", rate, speed, tilt_deg, fuel)
    assert m.touchdown_speed == pytest.approx(np.hypot(rate, speed), rel=1e-12)


def test_landing_through_the_nodes_agrees_with_core_only(tmp_path: Path) -> None:
    """Flight 0 of sweeps/landing-hover.yaml (dispersed: tilt, rates, altitude, velocity, wind,
    gusts, mass/inertia/thrust errors) through both nodes in lockstep, recorded, reduced from the
    bag with the core-only definitions: every metric, touchdown figures included, agrees to 1e-9."""
    spec = load_spec(REPO / "sweeps" / "landing-hover.yaml")
    check = through_ros(spec, 1, tmp_path)
    assert check.agree, check.mismatches
    row = check.ros_rows[0]
    assert row["outcome"] == "landed" and row["success"]
    assert row["touchdown_descent_rate"] < 0.5 and row["touchdown_ground_speed"] < 0.2


@pytest.mark.slow
def test_scenario_1_landed(tmp_path: Path) -> None:
    result, bag = fly_shipped("landing-scenario1", tmp_path)
    f = Flight.from_bag(check_bag(bag, result))
    _, rate, speed, tilt_deg, fuel = touchdown(f)
    assert rate < 0.5 and speed < 0.2 and tilt_deg < 5.0 and fuel > 30.0
    chute = [e for e in f.events if e[1] == EV_PARACHUTE_DEPLOYED]
    assert len(chute) == 1 and chute[0][0] < 1.0  # at once: from rest at 10 km it only saves fuel
