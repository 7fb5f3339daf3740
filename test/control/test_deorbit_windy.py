"""Dispersed de-orbit flights in a wind (the 200 km sweep's cases 88, 5.6 m/s, and 55, 4.4 m/s,
and others; scenario 0's case 96 for the MPC's last period), core-only: what the descent laws must
not do under the canopy and at the braking's end (issue 14's dispersed fuel).

Before the fixes this flight declared thruster 0 dead 0.2 s after the chute opened (the canopy's
torque in the wind, unexplained), flew the spinning three-thruster descent (9 rad/s of yaw),
stopped the fall 132 m under the hover and used 3.7 x the optimum's fuel to the hover band; with
the watch off it still turned its heading back to east as the braking began (0.9 rad/s of yaw,
half of two thrusters for ~2 s) and stopped 18 m under.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.combined import CollectiveHeadroom
from lander_autopilot.controllers.deorbit import DeorbitController, DescentToAltitude, Phase
from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import nominal_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import flown_periods
from lander_tools.sweep.metrics import in_hover_band
from lander_tools.sweep.spec import load_spec

SPEC = Path(__file__).resolve().parents[2] / "sweeps" / "deorbit-200km.yaml"
SPEC_0 = SPEC.with_name("deorbit.yaml")  # scenario 0's orbit
DEMAND = Demand(altitude=500.0)


def _flown(case_index: int, controller_index: int, spec: Path = SPEC,
           **params: object) -> Iterator[tuple[StateView, Any, Simulation]]:
    """The sweep's dispersed case ``case_index`` with its controller ``controller_index`` (``params``
    over the sweep's), flown as the sweep flies it (:func:`flown_periods`), a control period at a
    time: yields the state the law was given, the law after its update, and the simulation after
    the period; the spec's duration at most (200 km's sweep by default)."""
    for _t, s, ctrl, sim in flown_periods(load_spec(spec), controller_index, case_index, **params):
        assert sim.phase.name == "FLYING", sim.phase
        yield s, ctrl, sim


@pytest.mark.slow  # ~2500 s of simulated flight, ~6 s
def test_windy_descent_keeps_its_thrusters_and_heading_and_stops_at_the_hover():
    spec = load_spec(SPEC)
    nominal = nominal_scene(spec)
    case = draw_case(spec, 88, nominal.vehicle.n_thrusters)
    assert float(np.linalg.norm(case.wind_mean_W)) > 5.0  # the case this test is about
    yaw_rates: list[float] = []
    heading_at_braking = None
    for s, ctrl, sim in _flown(88, 0):  # noqa: B007 - sim: read after the loop (the period the hover began)
        if ctrl.phase is Phase.POWERED:
            yaw_rates.append(abs(float(s.omega_B[2])))
            if heading_at_braking is None and ctrl.descent.heading_W is not None:
                heading_at_braking = ctrl.descent.heading_W.copy()
        if ctrl.phase is Phase.HOVER:
            break
    assert ctrl.phase is Phase.HOVER
    # no false alarm under the canopy: all four thrusters stay in the allocation, no spin
    assert ctrl.descent.allocation is None and ctrl.descent.spin is None
    # the heading the braking began with is held (no yaw turn) and handed to the hover law
    assert heading_at_braking is not None
    np.testing.assert_array_equal(ctrl.hover.heading_W, heading_at_braking)
    assert max(yaw_rates) < 0.1  # rad/s; 0.9 with the east heading, 9 with the false alarm
    # the fall is stopped near the floor: within a period's braking at full thrust, not tens of metres under
    s = sim.state()
    h = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS
    axial = ctrl.descent.T_v / nominal.vehicle.mass(s.fuel)
    assert h > 500.0 - 0.5 * axial * 1.0**2, h  # ~4 m: a second of full-thrust deceleration


def _fly_mpc_to_the_band(case_index: int, **params: object) -> tuple[float, float]:
    """Core-only MPC flight of a dispersed case: (ground speed at the start of the hover phase [m/s],
    fuel from the powered descent's start to the first instant in the hover band [kg])."""
    end = load_spec(SPEC).end
    fuel0 = drift = None
    for s, ctrl, _sim in _flown(case_index, 1, **params):
        if ctrl.phase is Phase.POWERED and fuel0 is None:
            fuel0 = s.fuel
        if ctrl.phase is Phase.HOVER:
            up = s.r_W / float(np.linalg.norm(s.r_W))
            if drift is None:
                drift = float(np.linalg.norm(s.v_W - float(s.v_W @ up) * up))
            h = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS
            if in_hover_band(h - DEMAND.altitude, float(np.linalg.norm(s.v_W)), end.hover_band, end.hover_speed):
                assert fuel0 is not None
                return drift, fuel0 - s.fuel
    raise AssertionError("never in the hover band")


@pytest.mark.slow  # two flights, ~20 s
def test_mpc_planning_with_the_attitude_lag_brakes_the_drift_before_the_hover(monkeypatch):
    """The QP under the canopy brakes the drift late (drag pulls it back toward the wind's early on);
    planned with an instant thrust axis, the attitude loop flew that braking ~1 s late and the hover
    began still drifting, which the hover law took out on hover thrust. Both flights without the
    braking's integral action on the axis (``_axis_flown_as_asked``, since stop 40), as when the lag
    was added (with it the axis flies nearer the tilt asked for, and the instant plan's drift at the
    hover is smaller)."""
    from lander_autopilot.controllers.deorbit_mpc import DeorbitMpcController

    monkeypatch.setattr(DeorbitMpcController, "_axis_flown_as_asked", lambda self, t, s, L, d: d)
    spec = load_spec(SPEC)
    case = draw_case(spec, 55, nominal_scene(spec).vehicle.n_thrusters)
    assert float(np.linalg.norm(case.wind_mean_W)) > 4.0  # a steady wind, small gusts: the case this is about
    drift_instant, fuel_instant = _fly_mpc_to_the_band(55, attitude_lag=0.0)
    drift_lag, fuel_lag = _fly_mpc_to_the_band(55)
    print(f"drift at the hover {drift_instant:.3f} -> {drift_lag:.3f} m/s, fuel to the band {fuel_instant:.3f} -> {fuel_lag:.3f} kg")
    # The instant plan's drift was 0.93 m/s when the lag was added; the coast along the airflow
    # (stop 38) and the 1.5 m target (stop 40) took it to 0.203 and then 0.197 m/s, just under the
    # hover's speed, so the test no longer asks it to be over that speed: the lag's plan leaves
    # under half the instant plan's drift, and its hover begins within its own speed band.
    assert drift_lag < 0.5 * drift_instant
    assert drift_lag < spec.end.hover_speed
    assert fuel_lag < fuel_instant


class HoverBegins(NamedTuple):
    """Where a core-only flight's `hover` phase began (:func:`_hover_begins`)."""

    error: float  # [m] the altitude error over the demand
    drift: float  # [m/s] the ground speed
    ctrl: Any  # the law then


def _hover_begins(case_index: int, controller_index: int = 0, **params: object) -> HoverBegins:
    """The sweep's case flown core-only by its controller ``controller_index`` (0 scheduled, 1 MPC;
    ``params`` over the sweep's) to the start of its `hover` phase."""
    for s, ctrl, _sim in _flown(case_index, controller_index, **params):
        if ctrl.phase is Phase.HOVER:
            r = float(np.linalg.norm(s.r_W))
            climb = float(s.v_W @ s.r_W) / r
            return HoverBegins(r - c.MARS_RADIUS - DEMAND.altitude, float(np.linalg.norm(s.v_W - climb * s.r_W / r)), ctrl)
    raise AssertionError("no hover")


@pytest.mark.slow  # two flights, ~20 s
def test_braking_on_the_collective_the_attitude_law_leaves_stops_in_the_band(monkeypatch):
    """Case 196 (5.4 m/s of wind, 3.9 m/s of it downdraft): under the canopy the attitude law holds
    one thruster at full throttle through the braking. Planned on the full collective, aimed at the
    demand itself and on the drag scale learnt at the canopy's terminal speed (the law of stop 24),
    the limb ran out of thrust and the fall stopped 4.7 m under the hover (the hover law then climbed
    back on hover thrust: 1.37 x the optimum's fuel in the sweep); on the collective left (learnt at
    the mixer's floor too in a wind over FLOOR_LEARN_WIND), aimed stop_above over the demand and on
    the air fitted under the chute (FallDrag: that scale over-predicts the drag below the terminal
    speed in a downdraft), it stops within the band."""
    band = load_spec(SPEC).end.hover_band
    error, _drift, ctrl = _hover_begins(196)
    share = ctrl.descent.headroom.share
    monkeypatch.setattr(CollectiveHeadroom, "update", lambda self, *args: None)  # the full collective, as before
    fit_air = DeorbitController._fit_air

    def scale_only(self: DeorbitController, state: Any) -> None:  # and on the scale learnt, not the fit
        fit_air(self, state)
        self.descent.air = None

    monkeypatch.setattr(DeorbitController, "_fit_air", scale_only)
    error_full, _drift, ctrl_full = _hover_begins(196, stop_above=0.0)  # the limb aimed at the demand
    share_full = ctrl_full.descent.headroom.share
    print(f"braking ends {error_full:+.2f} m (full collective, aimed at the demand, scale learnt) -> {error:+.2f} m (share {share:.3f} learnt)")
    assert share_full == 0.0 and share > 0.02
    assert error_full < -band
    assert -band <= error <= band


@pytest.mark.slow  # two flights, ~20 s
def test_limb_margin_in_height_keeps_a_braking_that_falls_behind_in_the_band():
    """Case 261 (200 km sweep, held out until stop 40: 5.6 m/s of drift under the canopy, thruster
    errors -0.7, +2.6, -1.9 and +3.0 %): through the braking the attitude law's share of
    the collective was learnt at 0.10 (one thruster at full throttle), the limb's deceleration fell
    from 4.2 to 3.6 m/s^2 after the fall was on it, and the braking rode the ceiling to its end. With
    stop 40's margins, 5 % of the net thrust held back (``brake_fraction`` 0.95) and the limb
    ending 1 m over the demand, the fall stopped 2.10 m under the demand, outside the 2 m band, and
    the hover law climbed back (1.107 x the optimum in the replay). With the margin moved into
    height (0.96, the limb ending ``stop_above`` 1.75 m over the demand) it stops in the band."""
    band = load_spec(SPEC).end.hover_band
    error = _hover_begins(261).error
    error_before = _hover_begins(261, brake_fraction=0.95, stop_above=1.0).error
    print(f"braking ends {error_before:+.2f} m (0.95, 1 m over) -> {error:+.2f} m (0.96, 1.75 m over)")
    assert error_before < -band
    assert -band <= error <= band


@pytest.mark.slow  # two flights, ~20 s
def test_thrust_axis_correction_takes_the_drift_out_by_the_hover(monkeypatch):
    """Case 38 (2.5 m/s of drift under the canopy, 2.9 m/s of horizontal wind): through the braking
    the attitude law flew the thrust axis at under half the tilt asked for (the canopy's torque
    against a proportional-derivative law), and the hover began with 0.36 m/s of ground speed, 1.3 s
    of hover thrust to the band at rest (1.15 x the optimum's fuel). With integral action on the
    axis (DescentToAltitude.axis_bias) the hover begins within its own speed band."""
    spec = load_spec(SPEC)
    error, drift, _ctrl = _hover_begins(38)
    monkeypatch.setattr(DescentToAltitude, "axis_bias", lambda self, *args: None)
    error_plain, drift_plain, _ctrl = _hover_begins(38)
    print(f"ground speed at the hover {drift_plain:.3f} -> {drift:.3f} m/s (altitude error {error_plain:+.2f} -> {error:+.2f} m)")
    assert drift_plain > spec.end.hover_speed
    assert drift < spec.end.hover_speed
    assert abs(error) <= spec.end.hover_band


@pytest.mark.slow  # two MPC flights, ~40 s
def test_mpc_with_its_air_fit_and_plan_reserve_stops_the_fall_in_the_band():
    """Case 188 (density -12.9 %, 1.1 m/s of downdraft at the site, gusts 0.7 m/s): the QP braked on a
    drag scale learnt at the canopy's terminal speed (over-predicting the drag below it by 0.2-0.35
    m/s^2) at its thrust bound, and stopped the fall 7 m under the hover (1.45 x in the sweep). With
    the drag scale and wind fitted under the chute and 4 % of its bound kept in hand, it stops in
    the band; with the fit but no reserve it still rides its bound and stops under it."""
    band = load_spec(SPEC).end.hover_band
    error, _drift, ctrl = _hover_begins(188, 1)
    error_plain = _hover_begins(188, 1, plan_reserve=0.0, reference_thrust=0.95).error
    print(f"braking ends {error_plain:+.2f} m (no reserve) -> {error:+.2f} m (reserve {ctrl.settings.plan_reserve})")
    assert ctrl.air is not None and ctrl.mpc is not None
    assert ctrl.mpc.drag.k < 0.9 * ctrl._drag_k  # the fitted scale (0.87) went into the QP's drag
    assert error_plain < -band
    assert -band <= error <= band


def _hover_to_rest(case_index: int, **params: object) -> tuple[float, float]:
    """Scheduled law, core-only: (fuel [kg] from the start of the `hover` phase to the first instant
    within the sweep's band at its speed, the ground speed [m/s] as the hover began)."""
    spec = load_spec(SPEC)
    fuel0 = drift0 = None
    for s, ctrl, _sim in _flown(case_index, 0, **params):
        if ctrl.phase is not Phase.HOVER:
            continue
        up = s.r_W / float(np.linalg.norm(s.r_W))
        if fuel0 is None:
            climb = float(s.v_W @ up)
            fuel0, drift0 = float(s.fuel), float(np.linalg.norm(s.v_W - climb * up))
        error = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS - DEMAND.altitude
        if in_hover_band(error, float(np.linalg.norm(s.v_W)), spec.end.hover_band, spec.end.hover_speed):
            return fuel0 - float(s.fuel), drift0
    raise AssertionError("never within the band at its speed")


@pytest.mark.slow  # two flights, ~20 s
def test_hover_attitude_fast_enough_to_take_the_last_drift_out_under_the_canopy(monkeypatch):
    """Case 140 (6.2 m/s of wind from the north), braked as before stop 35 (the lag term counting
    the thrust asked for at the mixer's ceiling): the braking ends with ~0.3 m/s of drift and the
    thrust axis short of the tilt the drag at rest needs (the canopy's torque). With the ground-speed
    law's attitude poles (-2) the hover flies the axis there slowly, on hover thrust; at the hover's
    own poles (-4) it is at the band's speed on about half the fuel (1.07 -> 0.58 kg), from the same
    state (the braking is the same flight). Stop 30 measured this on case 164 (1.46 -> 0.74 kg),
    whose braking now ends under the band's speed (stop 31's horizontal loop), as case 140's does
    since stop 35 (the next test)."""
    monkeypatch.setattr(DescentToAltitude, "axial_at_ceiling", lambda self, m: None)
    fuel, drift = _hover_to_rest(140)
    fuel_slow, drift_slow = _hover_to_rest(140, hover_attitude_poles=[-2.0] * 6)
    print(f"hover fuel to the band at rest: {fuel_slow:.3f} kg (poles -2) -> {fuel:.3f} kg (poles -4); drift {drift:.3f} m/s")
    assert drift == drift_slow > load_spec(SPEC).end.hover_speed  # the same braking, ending over the band's speed
    assert fuel < 0.8 * fuel_slow


@pytest.mark.slow  # two flights and their optimum, ~25 s
def test_braking_at_the_mixers_ceiling_counts_the_thrust_it_gives_not_the_one_asked(monkeypatch):
    """Case 140 (6.2 m/s of wind from the north): the braking rides the mixer's ceiling (the
    attitude law's share on top of the collective) and the thrust flown is 10-30 % under the one
    asked for. The horizontal loop's lag term counted that missing thrust's horizontal part as
    speed already being taken out, asked for too little, and the hover began with 0.29 m/s of
    ground speed, over the band's 0.2: 1.080 x the optimum. Counting at the ceiling the thrust the
    mixer gave (``DescentToAltitude.axial_at_ceiling``), the drift is out by the hover: 1.032 x
    (docs/deorbit.md, "The thrust the lag term counts (stop 35)")."""
    speed = load_spec(SPEC).end.hover_speed
    end = _powered_end(140, 0)
    monkeypatch.setattr(DescentToAltitude, "axial_at_ceiling", lambda self, m: None)
    before = _powered_end(140, 0)
    print(f"ground speed as the hover begins {before.drift:.3f} -> {end.drift:.3f} m/s; "
          f"fuel to the band at rest {before.ratio:.4f} -> {end.ratio:.4f} x the optimum")
    assert end.drift < speed < before.drift
    assert end.ratio < 1.05 < before.ratio


@pytest.mark.slow  # one flight and one optimum, ~15 s
def test_fall_past_the_limbs_end_is_stopped_at_the_limbs_deceleration():
    """Case 196 (5.4 m/s of wind, 3.9 m/s of it downdraft): the collective saturated, the fall
    passes the limb's end (``stop_above`` over the demand) at 1.3 m/s (1.9 m/s with stop 30's
    horizontal loop). The velocity loop's demand
    there shrinks with its error, and the law of stop 30 crept that speed out over ~0.6 s at part of
    the collective: 1.097 x the optimum's fuel to the band at rest. Braking there at no less than
    the limb's deceleration (the one-period cap ending it), the fall stops within that deceleration's
    time and 1.030 x (``bench/deorbit_replay.py``)."""
    from lander_tools.sweep.flight import _chute_open, control_period, powered_optimum

    spec = load_spec(SPEC)
    handover = None
    t_end = speed = a_b = t_hover = ratio = None
    for s, ctrl, sim in _flown(196, 0):
        r = float(np.linalg.norm(s.r_W))
        error, climb = r - c.MARS_RADIUS - DEMAND.altitude, float(s.v_W @ s.r_W) / r
        if handover is None and ctrl.phase is Phase.POWERED:
            handover = (s.r_W.copy(), s.v_W.copy(), float(s.fuel), _chute_open(sim))
        if t_end is None and handover is not None and error < ctrl.descent.stop_above and climb < 0.0:
            t_end, speed = s.t, -climb
            a_b = ctrl.descent.braking_acceleration(sim.scene.vehicle.mass(float(s.fuel)), c.GM_MARS / (r * r))
        if t_hover is None and ctrl.phase is Phase.HOVER:
            t_hover = s.t
        if t_hover is not None and in_hover_band(error, float(np.linalg.norm(s.v_W)), spec.end.hover_band, spec.end.hover_speed):
            ratio = (handover[2] - float(s.fuel)) / powered_optimum(sim, handover, DEMAND.altitude)
            break
    assert ratio is not None, "never within the band at its speed"
    period = control_period(spec, sim.dt)[1]  # [s]
    print(f"past the limb's end at {speed:.2f} m/s, a_b {a_b:.2f} m/s^2: the fall stopped {t_hover - t_end:.1f} s later; "
          f"fuel to the band at rest {ratio:.4f} x the optimum")
    assert speed > 1.0  # the case this test is about: the braking fell behind its limb
    # stopped at a_b or more: speed / a_b, plus the period in which the end was passed and the capped last one
    assert t_hover - t_end <= speed / a_b + 2 * period + 1e-9
    assert ratio <= 1.05


@pytest.mark.slow  # three flights, ~30 s
def test_braking_takes_the_drift_out_before_its_shorter_end(monkeypatch):
    """Case 164 (5.2 m/s east, 3.3 m/s north of wind). With the fall past the limb's end braked at
    ``a_b`` the braking ends sooner, and with stop 28's horizontal loop (``LAG`` 0.7 s, ``SETTLE``
    1.5 s: the lag term held the loop's time constant near ``tau + LAG``) the hover began with
    0.30 m/s of ground speed, over the band's 0.2, and spent ~1 s of hover thrust on it (1.115 x
    the optimum in the replay); at 0.5 s and 0.8 s it begins with 0.19 m/s (1.042 x). Both flights
    count the thrust asked for at the mixer's ceiling, and brake on the limb's margins, as the law
    then did: counting the thrust the mix gave (stop 35, ``test_braking_at_the_mixers_ceiling_...``)
    also takes most of this drift out with the old ``LAG`` and ``SETTLE`` (0.108 m/s); on stop 41's
    margins (``brake_fraction`` 0.96, ``stop_above`` 1.75 m) that law, counting the thrust asked,
    begins the hover with 0.225 m/s (0.336 with the old ``LAG`` and ``SETTLE``), and the law as it
    is with 0.055 m/s."""
    speed = load_spec(SPEC).end.hover_speed
    drift_now = _hover_begins(164).drift
    then = {"brake_fraction": 0.95, "stop_above": 1.0}  # stop 31's limb
    monkeypatch.setattr(DescentToAltitude, "axial_at_ceiling", lambda self, m: None)
    drift = _hover_begins(164, **then).drift
    monkeypatch.setattr(DescentToAltitude, "LAG", 0.7)
    monkeypatch.setattr(DescentToAltitude, "SETTLE", 1.5)
    drift_before = _hover_begins(164, **then).drift
    print(f"ground speed as the hover begins: {drift_before:.3f} m/s (LAG 0.7 s, SETTLE 1.5 s) -> {drift:.3f} m/s; "
          f"the law as it is: {drift_now:.3f} m/s")
    assert drift < speed < drift_before
    assert drift_now < speed


class PoweredEnd(NamedTuple):
    """How a core-only flight's powered descent ended (:func:`_powered_end`)."""

    climb_max: float  # [m/s] the fastest climb in the powered descent after the fall's end
    ratio: float  # fuel from the powered descent's start to the first instant within the sweep's band at its speed, over the optimum
    fall_end: float  # [m] the altitude error where the fall first stopped (or, still falling, where it reached the band at rest)
    drift: float  # [m/s] the ground speed as the `hover` phase began
    coast_fuel: float  # [kg] fuel from the powered descent's start to the MPC's braking (NaN: scheduled law)
    #: the MPC's braking: the thrust axis's tilt flown over the one its QP asked for (each the axis's
    #: horizontal over its vertical part, summed over the braking's periods; NaN: scheduled law)
    axis_follow: float
    fuel: float  # [kg] from the powered descent's start to the first instant within the sweep's band at its speed


def _powered_end(case_index: int, controller_index: int, spec_path: Path = SPEC, **params: object) -> PoweredEnd:
    """The sweep's case flown core-only by its controller ``controller_index`` (0 scheduled, 1 MPC;
    ``params`` over the sweep's) to the band at rest: how its powered descent ended."""
    from lander_tools.sweep.flight import _chute_open, powered_optimum

    spec = load_spec(spec_path)
    handover = None
    stopped, climb_max, fall_end, drift, coast_fuel = False, 0.0, math.nan, math.nan, math.nan
    asked = flown = 0.0
    for s, ctrl, sim in _flown(case_index, controller_index, spec_path, **params):
        r = float(np.linalg.norm(s.r_W))
        error, climb = r - c.MARS_RADIUS - DEMAND.altitude, float(s.v_W @ s.r_W) / r
        if handover is None and ctrl.phase is Phase.POWERED:
            handover = (s.r_W.copy(), s.v_W.copy(), float(s.fuel), _chute_open(sim))
        if handover is not None and math.isnan(coast_fuel) and getattr(ctrl, "braking_begun", False):
            coast_fuel = handover[2] - float(s.fuel)
        if ctrl.phase is Phase.POWERED and getattr(ctrl, "braking_begun", False) and ctrl.thrust_L is not None:
            T, z = ctrl.thrust_L, ctrl._frame @ quat_to_matrix(s.q)[2]
            asked += float(np.linalg.norm(T[:2])) / float(T[2])
            flown += float(np.linalg.norm(z[:2])) / float(z[2])
        if handover is not None and math.isnan(fall_end) and climb >= 0.0:
            fall_end = error
        if math.isnan(drift) and ctrl.phase is Phase.HOVER:
            drift = float(np.linalg.norm(s.v_W - climb * s.r_W / r))
        stopped = stopped or (handover is not None and abs(error) < spec.end.hover_band and climb >= 0.0)
        if stopped and ctrl.phase is Phase.POWERED:
            climb_max = max(climb_max, climb)
        if handover is not None and in_hover_band(error, float(np.linalg.norm(s.v_W)), spec.end.hover_band,
                                                  spec.end.hover_speed):
            fuel = handover[2] - float(s.fuel)
            ratio = fuel / powered_optimum(sim, handover, DEMAND.altitude)
            if math.isnan(fall_end):  # in the band under the hover's speed, still (slowly) falling
                fall_end = error
            return PoweredEnd(climb_max, ratio, fall_end, drift, coast_fuel, flown / asked if asked > 0.0 else math.nan, fuel)
    raise AssertionError("never within the band at its speed")


@pytest.mark.slow  # two MPC flights from scenario 0's orbit and their optimum, ~50 s
def test_mpc_last_braking_period_stops_the_fall_not_into_a_climb(monkeypatch):
    """Scenario 0's sweep, case 96: the QP's steps are 15 ms at the end, and its last braking
    command, held for the whole 0.1 s period, overshot rest into a climb (0.92 m/s) that was then
    flown out: 1.147 x the optimum. Capped so that it cannot reverse the fall
    within the period (``DeorbitMpcController._stop_within_period``), the lander never climbs
    after the fall's end in the powered descent: 1.029 x. Both flights plan to the demand itself
    (``target_above`` 0) and fly the QP's thrust from the handover on (``COAST_COLLECTIVE`` 0), as
    when the cap was added: planned 1 m over the demand (the default since stop 34), or coasting
    along the airflow until the braking (since stop 38), or braking its last second at the constant
    deceleration to its target (``limb_time``, since stop 42), this case stops without the overshoot
    even uncapped; so both flights fly the QP to the end (``limb_time`` 0)."""
    from lander_autopilot.controllers import deorbit_mpc
    from lander_autopilot.controllers.deorbit_mpc import DeorbitMpcController

    monkeypatch.setattr(deorbit_mpc, "COAST_COLLECTIVE", 0.0)
    speed = load_spec(SPEC_0).end.hover_speed
    climb, ratio, *_ = _powered_end(96, 1, SPEC_0, target_above=0.0, limb_time=0.0)
    monkeypatch.setattr(DeorbitMpcController, "_stop_within_period", lambda self, T_L, *args: T_L)
    climb_before, ratio_before, *_ = _powered_end(96, 1, SPEC_0, target_above=0.0, limb_time=0.0)
    print(f"fastest climb after the fall's end {climb_before:.3f} -> {climb:.3f} m/s; "
          f"fuel to the band at rest {ratio_before:.4f} -> {ratio:.4f} x the optimum")
    assert climb < speed < climb_before
    assert ratio < 1.05 < ratio_before


@pytest.mark.slow  # two MPC flights from scenario 0's orbit and their optimum, ~50 s
def test_mpc_plans_to_rest_over_the_demand_so_a_plan_that_falls_behind_stops_in_the_band():
    """Scenario 0's sweep, case 78: its thrusters' own torque takes ~5 % of the collective, learnt
    only as the braking binds, and the plan falls behind. Planned to the demand itself, the fall
    stopped 2.6 m under it, outside the 2 m band, and the hover law's climb back into the band
    cost 0.14 of the optimum (1.193 x). Planned to rest ``target_above`` (1 m then) over the demand,
    the same shortfall stopped in the band (1.051 x; docs/deorbit.md, "The MPC's target (stop 34)").
    Since stop 40 the braking flies the axis's tilt it asks for, which leaves it less vertical thrust
    than the short tilt did, and the target is 1.5 m: 2.92 m and 1.206 x planned to the demand,
    1.44 m under it and 1.051 x planned over it; since stop 42, with its last second's vertical
    thrust bounded by the limb (the constant deceleration to its target), 2.82 m and 1.199 x,
    1.34 m and 1.042 x."""
    band = load_spec(SPEC_0).end.hover_band
    _, ratio_before, stop_before, *_ = _powered_end(78, 1, SPEC_0, target_above=0.0)
    _, ratio, stop, *_ = _powered_end(78, 1, SPEC_0)
    print(f"the fall stopped at {stop_before:+.2f} -> {stop:+.2f} m from the demand; "
          f"fuel to the band at rest {ratio_before:.4f} -> {ratio:.4f} x the optimum")
    assert stop_before < -band < stop < 0.0  # short of the target either way: the plan fell behind
    # the climb back into the band, ~2 s of hover thrust, is what the target over the demand saves
    assert ratio < ratio_before - 0.1


@pytest.mark.slow  # two MPC flights from 200 km and their optimum, ~50 s
def test_mpc_coasts_along_the_airflow_until_its_braking(monkeypatch):
    """The 200 km sweep's case 88 (5.6 m/s of wind): the MPC hands over ~2 s before its braking, and
    flying the QP's small thrust along the QP's own direction held the thrust axis off the airflow
    against the canopy's torque; the attitude law's differential burnt fuel over the whole coast.
    Coasting along the air fitted under the chute, with no thrust, until the QP asks for
    ``COAST_COLLECTIVE`` (``DeorbitMpcController._coast_along_air``), the coast burns a fraction of it
    and the whole descent less (docs/deorbit.md, "The MPC's coast (stop 38)"). Both flights without
    the braking's integral action on the axis (since stop 40), as when the coast was added: with it
    the braking flies the axis it asks for either way, and the coast's gain to the band is small
    (0.0007 x at stop 39's replays)."""
    from lander_autopilot.controllers import deorbit_mpc
    from lander_autopilot.controllers.deorbit_mpc import DeorbitMpcController

    monkeypatch.setattr(DeorbitMpcController, "_axis_flown_as_asked", lambda self, t, s, L, d: d)
    end = _powered_end(88, 1)
    monkeypatch.setattr(deorbit_mpc, "COAST_COLLECTIVE", 0.0)  # the QP's thrust flown from the handover
    before = _powered_end(88, 1)
    print(f"fuel to the braking {before.coast_fuel:.3f} -> {end.coast_fuel:.3f} kg; to the band at rest "
          f"{before.fuel:.3f} -> {end.fuel:.3f} kg, {before.ratio:.4f} -> {end.ratio:.4f} x the optimum")
    assert end.coast_fuel < 0.5 * before.coast_fuel
    # the coast's saving is not spent later in the braking: at least half of it is kept to the band
    # (0.155 kg saved in the coast, 0.125 kg over the whole descent, 1.0548 -> 1.0461 x, at stop 40)
    assert before.fuel - end.fuel > 0.5 * (before.coast_fuel - end.coast_fuel)


@pytest.mark.slow  # two MPC flights from 200 km and their optimum, ~50 s
def test_mpc_braking_flies_the_thrust_axis_its_plan_asks_for(monkeypatch):
    """The 200 km sweep's case 24 (4.7 m/s of wind, 1.3 x the model's drag): under the canopy the
    attitude law (proportional-derivative) flew the thrust axis at about half the tilt the QP asked
    for, the canopy's torque pulling it back toward the airflow, so the drift was taken out late,
    in a swing of the axis at the braking's end (the fuel's ratio read as the sweep reads it). With
    integral action on the axis flown against the one asked
    (``DeorbitMpcController._axis_flown_as_asked``, the scheduled law's since stop 28) the axis
    flies the tilt asked for and the descent costs less (docs/deorbit.md, "The MPC's thrust
    axis, flown as asked (stop 40)"). Both flights fly the QP to the end (``limb_time`` 0), as when
    the integral was added: the last second's limb (stop 42) asks for no tilt once the fall has
    passed its target, which moves the ratio measured (the shipped law flies this case at 1.0495 x)."""
    from lander_autopilot.controllers.deorbit_mpc import DeorbitMpcController

    end = _powered_end(24, 1, limb_time=0.0)
    monkeypatch.setattr(DeorbitMpcController, "_axis_flown_as_asked", lambda self, t, s, L, d: d)
    before = _powered_end(24, 1, limb_time=0.0)
    print(f"tilt flown over tilt asked in the braking {before.axis_follow:.3f} -> {end.axis_follow:.3f}; "
          f"to the band at rest {before.ratio:.4f} -> {end.ratio:.4f} x the optimum")
    # the canopy's weathervane stiffness is about the attitude law's: at most half the tilt flown
    # without the integral (0.43 measured); with it, over a braking of ~5 s that the 2 s integral and
    # the loop's 1 s lag trail as the asked tilt ramps up, 0.61
    assert before.axis_follow < 0.5
    assert end.axis_follow > before.axis_follow + 0.1
    assert end.ratio < before.ratio - 0.005  # 1.0724 -> 1.0623 measured (target 1.5 m, stop 40)


@pytest.mark.slow  # two MPC flights from 200 km and their optimum, ~50 s
def test_mpc_flying_the_tilt_it_asks_for_plans_to_rest_higher_over_the_demand():
    """The 200 km sweep's case 233 (drawn past the sweep's 200 flights: one of the held-out cases the
    axis's integral action was measured on, docs/deorbit.md, "The MPC's thrust axis, flown as asked (stop 40)"): with
    the braking flying the tilt its QP asks for, the short tilt's extra vertical thrust, a margin
    the plan had counted without knowing, is gone. Planned to rest 1 m over the demand (the target
    until stop 39) the fall stopped 2.36 m under it, outside the 2 m band, and the climb back cost
    0.1 of the optimum (1.150 x); planned 1.5 m over it (``target_above``'s default) it stops in
    the band (-1.81 m, 1.048 x; since stop 42, with its last second's vertical thrust bounded by
    the limb, the constant deceleration to its target, -2.22 m and 1.131 x against -1.66 m and
    1.040 x)."""
    band = load_spec(SPEC).end.hover_band
    _, ratio_before, stop_before, *_ = _powered_end(233, 1, target_above=1.0)
    _, ratio, stop, *_ = _powered_end(233, 1)
    print(f"the fall stopped at {stop_before:+.2f} -> {stop:+.2f} m from the demand; "
          f"fuel to the band at rest {ratio_before:.4f} -> {ratio:.4f} x the optimum")
    assert stop_before < -band < stop
    assert ratio < ratio_before - 0.05  # the climb back into the band, ~2 s of hover thrust


@pytest.mark.slow  # two MPC flights from scenario 0's orbit and their optimum, ~50 s
def test_mpc_last_second_brakes_at_constant_deceleration_to_its_target():
    """Scenario 0's case 203 (drawn past the sweep's 200 flights: held out at stop 39). In its last
    second the QP's plan is degenerate along the vertical (the end time fixed, every profile that
    stops at the target costs the same impulse), and once its end recedes it coasts and brakes
    late: a period at a collective of 0.22 at 1.5 m/s of fall, then full thrust, four periods for
    the last 1.5 m/s, 1.0547 x the optimum. With the last second's vertical thrust bounded by the
    constant deceleration to rest at the target (``limb_time`` 1 s, ``DescentMpc._last_second``),
    1.0391 x (docs/deorbit.md, "The MPC's last second (stop 42)")."""
    band = load_spec(SPEC_0).end.hover_band
    _, ratio_before, stop_before, *_ = _powered_end(203, 1, SPEC_0, limb_time=0.0)
    _, ratio, stop, *_ = _powered_end(203, 1, SPEC_0)
    print(f"the fall stopped at {stop_before:+.2f} -> {stop:+.2f} m from the demand; "
          f"fuel to the band at rest {ratio_before:.4f} -> {ratio:.4f} x the optimum")
    assert -band < stop < band
    assert ratio < ratio_before - 0.005
    assert ratio < 1.05 < ratio_before
