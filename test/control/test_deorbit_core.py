"""The de-orbit law flown in the core simulation (no ROS): each phase fires at its condition, the orbit
reached is the plan's, and the lander gets down safely with the stabiliser off."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.deorbit import DeorbitController, Phase, thrust_axis_attitude
from lander_autopilot.guidance.deorbit import Orbit
from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.scenes import load_scene
from lander_sim.scenes.vehicles import lander
from lander_sim.simulation import Simulation


def _orbit_scene(altitude: float | None):
    sc = load_scene("circular-orbit")  # scenario 0: 1.2 R
    y = sc.initial_state.copy()
    if altitude is not None:
        r = c.MARS_RADIUS + altitude
        y[0:3] = (r, 0.0, 0.0)
        y[3:6] = (0.0, -math.sqrt(c.GM_MARS / r), 0.0)
    return dataclasses.replace(sc, vehicle=lander("canted"), initial_state=y, stabiliser=False)


def test_thrust_axis_attitude_points_body_z_and_keeps_the_yaw():
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        qd = thrust_axis_attitude(q, d)
        R, Rd = quat_to_matrix(q), quat_to_matrix(qd)
        np.testing.assert_allclose(Rd[2], d, atol=1e-12)
        # smallest rotation: its axis is perpendicular to both z axes, so no part of it turns about d
        M = Rd.T @ R  # world-frame rotation taking the old body axes to the new (R_d = R M^T)
        axis = np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
        if np.linalg.norm(axis) > 1e-9:
            assert abs(float(axis @ R[2])) < 1e-9 and abs(float(axis @ d)) < 1e-9


def _fly(sc, demands):
    """Fly the de-orbit law; ``demands(t, ctrl, state)`` gives the demand. Returns the log of the flight."""
    sim = Simulation(sc)
    ctrl = DeorbitController(sc.vehicle)
    log = {"periapsis": [], "altitude": [], "fuel": {}, "end": None, "states": []}
    while sim.t < 10_000.0 and log["end"] is None:
        s = sim.state()
        demand = demands(sim.t, ctrl, s)
        if demand is None:
            break
        out = ctrl.update(sim.t, s, demand)
        if ctrl.phase is Phase.BURN or (ctrl.log.transitions and ctrl.log.transitions[-1][2] is Phase.COAST
                                        and ctrl.log.transitions[-1][0] == sim.t):
            log["periapsis"].append((sim.t, Orbit.of(s.r_W, s.v_W).periapsis_radius - c.MARS_RADIUS))
        log["altitude"].append((sim.t, float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS))
        log["fuel"].setdefault(ctrl.phase.value, s.fuel)  # fuel on board as each phase begins
        log["states"].append((sim.t, ctrl.phase, s))
        for r in out.requests:
            if r.kind == "deploy_parachute":
                sim.deploy_parachute()
        sim.set_throttles(out.throttles)
        sim.step()
        for e in sim.drain_events():
            if e.kind.name in ("LANDED", "CRASHED", "HARD_LANDING"):
                log["end"] = e
    return ctrl, log


def _check_orbit_phases(sc, ctrl, log):
    plan = ctrl.plan
    assert plan is not None
    steps = [(t, a.value, b.value) for t, a, b, _ in ctrl.log.transitions]
    assert [s[1:] for s in steps[:6]] == [("deorbit-slew", "deorbit-burn"), ("deorbit-burn", "coast"),
                                          ("coast", "entry"), ("entry", "parachute"),
                                          ("parachute", "powered-descent"), ("powered-descent", "hover")]
    dt = sc.dt
    # burn: at the first step at or after the planned start
    assert plan.burn_start <= steps[0][0] < plan.burn_start + dt
    # coast: at the first state whose osculating periapsis is at or under the plan's
    t_coast = steps[1][0]
    before = [p for t, p in log["periapsis"] if t < t_coast]
    at = [p for t, p in log["periapsis"] if t == t_coast]
    assert at and at[0] <= plan.periapsis_altitude < before[-1]
    # entry: at the first state below the top of the atmosphere
    t_entry = steps[2][0]
    prev = [a for t, a in log["altitude"] if t < t_entry][-1]
    now = [a for t, a in log["altitude"] if t == t_entry][0]
    assert now < c.EXOSPHERE_ALTITUDE <= prev
    # parachute: at the step the descent law asked for it, the chute's drag and speed within the
    # law's margin of the canopy's limits (the chute survived: the flight reached the hover)
    t_chute = steps[3][0]
    s = next(st for t, _, st in log["states"] if t == t_chute)
    h = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS
    v = float(np.linalg.norm(s.v_W))
    rho = c.ATMOSPHERE_SURFACE_DENSITY * math.exp(-h / c.ATMOSPHERE_SCALE_HEIGHT)
    drag = 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2 * rho * v * v
    assert v <= ctrl.chute_margin * c.PARACHUTE_MAX_SPEED and drag <= ctrl.chute_margin * c.PARACHUTE_MAX_DRAG
    assert h >= ctrl.descent.law.chute_min_altitude
    # powered descent: at the first step the descent law brakes (leaves its coast mode), never
    # while the chute alone still decelerates harder than the law's braking limb would
    t_pow = steps[4][0]
    s = next(st for t, _, st in log["states"] if t == t_pow)
    assert not ctrl.chute.waits(s, ctrl.chute_open, ctrl.descent)
    # The burn's fuel is the plan's rocket equation, give or take one step flat out (the cutoff falls
    # on a step) and the attitude law's differential throttle on top of the collective.
    burnt = log["fuel"]["deorbit-burn"] - log["fuel"]["coast"]
    flat_out = sum(t.fuel_rate for t in sc.vehicle.thrusters) * dt
    assert abs(burnt - plan.fuel) <= flat_out + 0.02 * plan.fuel
    return steps


def _held_then_land(hold: float = 30.0, band: float = 2.0, speed: float = 0.2):
    """Demand 500 m; once the hover has been held ``hold`` s within ``band`` m and ``speed`` m/s, demand 0."""
    held = {"since": None, "done": False}

    def demands(t, ctrl, s):
        if held["done"]:
            return Demand(altitude=0.0)
        ok = ctrl.phase is Phase.HOVER and abs(float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS - 500.0) < band \
            and float(np.linalg.norm(s.v_W)) < speed
        held["since"] = (held["since"] if held["since"] is not None else t) if ok else None
        if held["since"] is not None and t - held["since"] >= hold - 1e-9:
            held["done"] = True
        return Demand(altitude=0.0 if held["done"] else 500.0)
    return demands


@pytest.mark.slow  # some 40 s of simulated orbit, entry and descent each
@pytest.mark.parametrize("altitude", [None, 200e3], ids=["scenario-0-orbit", "200km"])
def test_from_orbit_to_a_held_hover_then_a_landing_on_demand(altitude):
    # The mission's acceptance: the hover at the demand (500 m) within 2 m and below 0.2 m/s, held 30 s;
    # then, on demand, a touchdown within the landing issue's limits (descent rate < 0.5 m/s, ground
    # speed < 0.2 m/s, tilt < 5 deg).
    sc = _orbit_scene(altitude)
    ctrl, log = _fly(sc, _held_then_land())
    steps = _check_orbit_phases(sc, ctrl, log)
    assert [b for _, _, b in steps][-3:] == ["powered-descent", "hover", "landing"]
    end = log["end"]
    assert end is not None and end.kind.name == "LANDED", end
    v = end.values
    assert v["descent_rate"] < 0.5 and v["ground_speed"] < 0.2 and v["tilt_deg"] < 5.0 and v["fuel_left"] > 0.0


def test_start_in_refuses_the_phases_that_need_the_plan():
    from lander_autopilot.controllers.base import ControllerError

    ctrl = DeorbitController(lander("canted"))
    with pytest.raises(ControllerError, match="start_in"):
        ctrl.start_in(Phase.BURN)
