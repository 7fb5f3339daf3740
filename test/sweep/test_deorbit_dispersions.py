"""The de-orbit sweeps' dispersions, checked by physics on the flown scene; the hover-hold
criterion on short flights; the new metrics; spec errors naming the key.

Tolerances: geometry identities hold to rounding, 1e-12 relative on quantities of order one
(angles, unit vectors, energy ratios) and 1e-6 m on radii of 3.4e6-4.1e6 m (their last bit is
~5e-10 m; a radius is a sum and a square root of such numbers).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_sim.physics.constants import GM_MARS
from lander_sim.physics.models.base import Inputs
from lander_sim.simulation import Simulation, build_dynamics
from lander_tools.sweep import batched, flight
from lander_tools.sweep.case_scene import (
    NotRepresentable,
    canted_directions,
    flown_scene,
    nominal_scene,
    orbit_start,
    write_case_scene,
)
from lander_tools.sweep.dispersion import FlightCase, draw_case
from lander_tools.sweep.metrics import BandSample, HoverHold, altitude_and_tilt, band_entry_fuel
from lander_tools.sweep.ros_path import compare_rows
from lander_tools.sweep.spec import NONDETERMINISTIC_METRICS, SweepSpecError, parse_spec
from lander_tools.sweep.summary import format_summary, summarise

from .conftest import same_rows

NEW = {
    "orbit_altitude": {"uniform": {"min": -10000.0, "max": 10000.0}},
    "orbit_phase": {"uniform": {"min": 0.0, "max": 2.0 * math.pi}},
    "density_error": {"uniform": {"min": -0.3, "max": 0.3}},
    "thruster_cant_error": {"uniform": {"min": 0.0, "max": 0.00873}},
}
ORBIT = {"name": "orbit", "scene": "deorbit", "controllers": ["deorbit"], "flights": 10, "seed": 14,
         "end": {"duration": 4700.0, "hover_hold": 30.0}, "dispersions": NEW}
#: Hover-hold on scenario 7 (canted): starts 50 m above the 500 m demand, tilted and turning. The
#: combined law holds the altitude but not the ground speed: it drifts on at ~0.207 m/s.
HOLD = {"name": "hold", "scene": "hover-canted", "controllers": ["combined"], "flights": 2, "seed": 5,
        "end": {"duration": 20.0, "hover_window": 1.0, "hover_hold": 2.0, "hover_band": 2.0, "hover_speed": 0.5},
        "metrics": ["hover_time", "fuel_left", "powered_fuel", "flight_time", "compute_time", "mpc_solve_time_p99"]}


@pytest.fixture(scope="module")
def orbit():
    return parse_spec(ORBIT, "orbit")


def _r_v(scene):
    y = scene.initial_state
    return np.array(y[0:3]), np.array(y[3:6])


def _angle(a, b):
    """Angle between two vectors [rad], accurate at small angles (atan2 of |a x b| and a . b)."""
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


# --------------------------------------------------------------------------- each dispersion


@pytest.mark.parametrize("dr", [-10000.0, 7321.5, 10000.0])
def test_orbit_altitude_gives_the_circular_orbit_at_the_new_radius(orbit, dr):
    r0, v0 = _r_v(nominal_scene(orbit))
    r, v = _r_v(flown_scene(orbit, FlightCase(0, 0, orbit_altitude=dr)))
    rn = float(np.linalg.norm(r))
    assert rn - float(np.linalg.norm(r0)) == pytest.approx(dr, abs=1e-6)
    assert _angle(r, r0) == pytest.approx(0.0, abs=1e-12)  # moved along r_hat only
    # Circular: v^2 = GM / r (vis-viva with a = r), velocity perpendicular to r, specific energy -GM / 2r.
    assert float(v @ v) * rn / GM_MARS == pytest.approx(1.0, rel=1e-12)
    assert float(r @ v) / (rn * float(np.linalg.norm(v))) == pytest.approx(0.0, abs=1e-12)
    assert (0.5 * float(v @ v) - GM_MARS / rn) / (-GM_MARS / (2.0 * rn)) == pytest.approx(1.0, rel=1e-12)
    assert _angle(np.cross(r, v), np.cross(r0, v0)) == pytest.approx(0.0, abs=1e-12)  # same plane, same sense


def test_orbit_altitude_keeps_the_shape_of_a_non_circular_orbit():
    def elements(r, v):
        rn = np.linalg.norm(r)
        a = 1.0 / (2.0 / rn - float(v @ v) / GM_MARS)
        e = np.cross(v, np.cross(r, v)) / GM_MARS - r / rn
        return a, e

    r0, v0 = np.array([3.6e6, 1.0e5, -2.0e4]), np.array([150.0, 3600.0, 400.0])
    r1, v1 = orbit_start(r0, v0, 25000.0, 0.0)
    k = float(np.linalg.norm(r1) / np.linalg.norm(r0))
    (a0, e0), (a1, e1) = elements(r0, v0), elements(r1, v1)
    assert a1 / a0 == pytest.approx(k, rel=1e-12)  # scaled about the planet's centre ...
    assert np.allclose(e1, e0, rtol=0.0, atol=1e-12) and np.linalg.norm(e0) > 0.05  # ... same eccentricity vector


@pytest.mark.parametrize("phase", [0.3, 2.0, 4.9])
def test_orbit_phase_rotates_the_start_about_the_orbit_normal(orbit, phase):
    r0, v0 = _r_v(nominal_scene(orbit))
    r, v = _r_v(flown_scene(orbit, FlightCase(0, 0, orbit_phase=phase)))
    n0 = np.cross(r0, v0) / np.linalg.norm(np.cross(r0, v0))
    assert np.linalg.norm(r) == pytest.approx(np.linalg.norm(r0), abs=1e-6)
    assert np.linalg.norm(v) == pytest.approx(np.linalg.norm(v0), rel=1e-12)
    assert _angle(np.cross(r, v), n0) == pytest.approx(0.0, abs=1e-12)
    # r turned by exactly the drawn angle about n (signed, in [0, 2 pi)), and v by the same.
    for a, b in ((r0, r), (v0, v)):
        turned = math.atan2(float(np.cross(a, b) @ n0), float(a @ b)) % (2.0 * math.pi)
        assert turned == pytest.approx(phase, abs=1e-12)
    # The attitude is not turned with the orbit (kept in the world frame).
    assert np.array_equal(flown_scene(orbit, FlightCase(0, 0, orbit_phase=phase)).initial_state[6:10],
                          nominal_scene(orbit).initial_state[6:10])


def test_density_error_scales_the_flown_atmosphere_exactly(orbit):
    e = -0.2371
    nominal, flown = nominal_scene(orbit), flown_scene(orbit, FlightCase(0, 0, density_error=e))
    a0, a1 = nominal.models.get("atmosphere"), flown.models.get("atmosphere")
    assert a1.surface_density == a0.surface_density * (1.0 + e)
    assert (a1.scale_height, a1.exosphere) == (a0.scale_height, a0.exosphere)
    # Physics: the drag acceleration at a state inside the atmosphere is (1 + e) times the nominal one.
    y = np.array(nominal.initial_state, dtype=float)
    y[0:3] = y[0:3] / np.linalg.norm(y[0:3]) * (3396200.0 + 40000.0)
    y[3:6] = [0.0, -3000.0, 200.0]
    acc = []
    for sc in (nominal, flown):
        out = np.zeros(6)
        build_dynamics(sc, Inputs(throttles=np.zeros(4))).accelerations(0.0, y, out)
        acc.append(out[0:3].copy())
    gravity = -GM_MARS * y[0:3] / np.linalg.norm(y[0:3]) ** 3
    drag0, drag1 = acc[0] - gravity, acc[1] - gravity
    assert np.linalg.norm(drag0) > 1e-3
    assert np.allclose(drag1, (1.0 + e) * drag0, rtol=1e-9, atol=0.0)


def test_each_thruster_is_tilted_by_exactly_its_drawn_cant(orbit):
    cant, az = (0.00873, 0.004, -0.006, 0.0005), (0.0, 1.3, 3.9, 5.5)
    nominal = nominal_scene(orbit)
    flown = flown_scene(orbit, FlightCase(0, 0, thruster_cant=cant, thruster_cant_azimuth=az))
    axes = []
    for t0, t1, c in zip(nominal.vehicle.thrusters, flown.vehicle.thrusters, cant):
        d0, d1 = np.asarray(t0.direction_B), np.asarray(t1.direction_B)
        assert np.linalg.norm(d1) == pytest.approx(1.0, abs=1e-15)
        assert _angle(d0, d1) == pytest.approx(abs(c), abs=1e-12)
        axes.append(np.cross(d0, d1) / np.linalg.norm(np.cross(d0, d1)))
        assert np.array_equal(t1.position_B, t0.position_B) and t1.max_thrust == t0.max_thrust
    assert min(_angle(a, b) for a, b in zip(axes, axes[1:])) > 0.1  # a different axis per thruster
    # Physics: thruster i alone at full throttle pushes along -d_i' with T_max (body frame).
    y = np.array(flown.initial_state, dtype=float)
    for i, t1 in enumerate(flown.vehicle.thrusters):
        on, off = np.zeros(6), np.zeros(6)
        dyn = build_dynamics(flown, Inputs(throttles=np.eye(4)[i]))
        dyn.accelerations(0.0, y, on)
        build_dynamics(flown, Inputs(throttles=np.zeros(4))).accelerations(0.0, y, off)
        force_B = dyn.rotation_matrix(y) @ (on[0:3] - off[0:3]) * (flown.vehicle.dry_mass + y[13])
        assert np.allclose(force_B, -np.asarray(t1.direction_B) * t1.max_thrust, rtol=0.0, atol=1e-9)
    # The controller's model is the nominal vehicle, untouched.
    assert all(np.array_equal(a.direction_B, b.direction_B) for a, b in
               zip(nominal.vehicle.thrusters, nominal_scene(orbit).vehicle.thrusters))


def test_the_azimuth_spans_the_axes_perpendicular_to_the_thruster():
    d = np.array([0.25, 0.0, -1.0]) / math.hypot(0.25, 1.0)
    tilted = canted_directions([d] * 8, (0.01,) * 8, tuple(np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)))
    axes = [np.cross(d, t) / np.linalg.norm(np.cross(d, t)) for t in tilted]
    assert all(abs(float(a @ d)) < 1e-12 for a in axes)
    turns = [math.atan2(float(np.cross(axes[0], a) @ d), float(axes[0] @ a)) % (2 * math.pi) for a in axes]
    assert np.allclose(turns, np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False), atol=1e-9)


def test_draws_depend_on_seed_and_index_only(orbit):
    few = dataclasses.replace(orbit, flights=3)
    alone = parse_spec({**ORBIT, "dispersions": {"density_error": NEW["density_error"]}}, "alone")
    a, b = draw_case(orbit, 7, 4), draw_case(few, 7, 4)
    assert a == b and draw_case(orbit, 7, 4) == a  # the sweep's size and the call order do not matter
    assert draw_case(alone, 7, 4).density_error == a.density_error  # nor the other dispersions
    c = draw_case(orbit, 8, 4)
    assert len({a.orbit_altitude, c.orbit_altitude}) == 2 and a.thruster_cant != c.thruster_cant
    other = draw_case(dataclasses.replace(orbit, seed=15), 7, 4)
    assert other.orbit_phase != a.orbit_phase
    assert len(a.thruster_cant) == len(a.thruster_cant_azimuth) == 4
    assert all(0.0 <= x <= 0.00873 for x in a.thruster_cant)


def test_the_fast_set_up_of_the_batched_core_reproduces_the_new_dispersions():
    # hover-canted starts at rest (no orbit plane): orbit_altitude, density and cant apply.
    data = {**HOLD, "flights": 4, "end": {"duration": 5.0, "hover_window": 1.0},
            "dispersions": {k: NEW[k] for k in ("orbit_altitude", "density_error", "thruster_cant_error")}}
    spec = parse_spec(data, "fast")
    tpl = batched.template_of(spec)
    assert tpl.why_not is None
    fast = [batched.setup_flight_fast(spec, i, tpl) for i in range(4)]
    ref = [batched.setup_flight(spec, i, 4) for i in range(4)]
    a, b = batched.pack_flights(fast, 10, tpl), batched.pack_flights(ref, 10)
    for k in b:
        assert np.ascontiguousarray(a[k]).tobytes() == np.ascontiguousarray(b[k]).tobytes(), k


def test_a_case_the_scene_cannot_carry_is_refused_naming_the_dispersion(tmp_path):
    spec = parse_spec({**HOLD, "dispersions": {"orbit_phase": NEW["orbit_phase"]}}, "rest")
    with pytest.raises(NotRepresentable, match=r"dispersions\.orbit_phase"):
        flight.preflight(spec)  # hover-canted starts at rest: no orbit plane to rotate in
    orbit = parse_spec(ORBIT, "orbit")
    with pytest.raises(NotRepresentable, match=r"dispersions\.thruster_cant_error"):
        write_case_scene(orbit, draw_case(orbit, 0, 4), tmp_path)  # no scene key for it: not through ROS
    write_case_scene(orbit, dataclasses.replace(draw_case(orbit, 0, 4), thruster_cant=(), thruster_cant_azimuth=()),
                     tmp_path)


# --------------------------------------------------------------------------- hover hold


def test_hover_hold_needs_an_unbroken_run():
    h = HoverHold(hold=1.0, band=2.0, speed_limit=0.2)
    feed = [(0.0, 3.0, 0.0), (0.5, 1.0, 0.1), (1.0, 1.0, 0.3), (1.5, -1.9, 0.1), (2.0, 0.0, 0.0), (2.5, 2.0, 0.2)]
    held = [h.update(*x) for x in feed]
    assert held == [False, False, False, False, False, True] and h.start == 1.5


def _reference_hold(spec, index):
    """The first instant a run in the band (alt error and |v|) lasting end.hover_hold ends, flown by
    an independent copy of the loop (Simulation + controller, no early stop)."""
    from lander_autopilot.controllers import Demand, make_controller

    sc0 = nominal_scene(spec)
    sim = Simulation(flown_scene(spec, draw_case(spec, index, 4)))
    ctrl = make_controller("combined", sc0.vehicle)
    e, start, demand = spec.end, None, flight.base_demand_altitude(sc0)
    for k in range(int(round(e.duration / sim.dt)) + 1):
        t, st = k * sim.dt, sim.state()
        h, _ = altitude_and_tilt(st.r_W, st.q)
        if abs(h - demand) <= e.hover_band and float(np.linalg.norm(st.v_W)) <= e.hover_speed:
            start = t if start is None else start
            if t - start >= e.hover_hold - 1e-9:
                return start, t
        else:
            start = None
        sim.set_throttles(ctrl.update(t, st, Demand(altitude=demand)).throttles)
        sim.step()
    return None, None


def test_a_held_hover_succeeds_and_stops_the_flight_there():
    spec = parse_spec(HOLD, "hold")
    row = flight.fly_case(spec, 0, 0).row
    start, end = _reference_hold(spec, 0)
    assert start is not None and start > 1.0  # it starts 50 m above: the band is reached later
    assert row["outcome"] == "hovered" and row["success"]
    assert row["hover_time"] == pytest.approx(start, abs=1e-9) and row["flight_time"] == pytest.approx(end, abs=1e-9)
    assert row["fuel_left"] > 0.0 and math.isnan(row["powered_fuel"])  # combined has no modes
    assert row["compute_time"] > 0.0 and math.isnan(row["mpc_solve_time_p99"])


@pytest.mark.parametrize("end, outcome", [
    ({"duration": 8.0, "hover_hold": 7.5}, "no-hover"),  # the band is not reached by 0.5 s
    ({"duration": 20.0, "hover_hold": 1.0, "hover_speed": 0.2}, "no-hover"),  # the drift stays above 0.2 m/s
])
def test_a_hover_not_held_in_time_fails(end, outcome):
    spec = parse_spec({**HOLD, "end": {**end, "hover_window": 1.0}}, "short")
    row = flight.fly_case(spec, 0, 0).row
    assert (row["outcome"], row["success"]) == (outcome, False)
    assert row["flight_time"] == pytest.approx(end["duration"]) and math.isnan(row["hover_time"])


def test_a_touchdown_fails_a_hover_hold_sweep():
    data = {**HOLD, "end": {"duration": 40.0, "demand_step_time": 0.0, "hover_window": 1.0, "hover_hold": 5.0},
            "dispersions": {"demand_altitude_step": {"fixed": -700.0}}}  # demand 0: down to the ground
    row = flight.fly_case(parse_spec(data, "down"), 0, 0).row
    assert row["outcome"] in ("landed", "crashed") and not row["success"]


def test_powered_fuel_and_mpc_figures_come_from_the_controller(monkeypatch):
    """A stand-in law: coasts (no thrust) in mode 'coast' until 1 s, flies the combined law in
    'powered-descent', then coasts again in 'hover' from 4 s; so the fuel burnt between the first
    powered-descent and the first hover answer is the whole flight's. Its diagnostics() are reported."""
    from lander_autopilot.controllers.base import ControlOutput

    spec = parse_spec({**HOLD, "end": {"duration": 6.0, "hover_window": 1.0},
                       "metrics": ["fuel_used", "powered_fuel", "mpc_solve_time_p99", "mpc_solve_time_median"]}, "modes")
    ctrl = flight.case_controller(spec, 0, nominal_scene(spec).vehicle)
    inner = ctrl.update

    def update(t, state, demand):
        out = inner(t, state, demand)
        if 1.0 <= t < 4.0 - 1e-9:
            return dataclasses.replace(out, mode="powered-descent")
        return ControlOutput(np.zeros(4), False, np.zeros(4), mode="hover" if t > 1.0 else "coast")

    monkeypatch.setattr(ctrl, "update", update)
    monkeypatch.setattr(ctrl, "diagnostics", lambda: {"mpc_solve_time_p99": 0.025, "mpc_solve_time_median": 0.007},
                        raising=False)
    row = flight.fly_case(spec, 0, 0).row
    assert row["fuel_used"] > 0.1 and row["powered_fuel"] == pytest.approx(row["fuel_used"], rel=1e-12)
    assert (row["mpc_solve_time_p99"], row["mpc_solve_time_median"]) == (0.025, 0.007)


def test_compute_time_is_left_out_of_every_determinism_check():
    assert set(NONDETERMINISTIC_METRICS) == {"compute_time", "mpc_solve_time_p99", "mpc_solve_time_median"}
    spec = parse_spec({**HOLD, "metrics": ["hover_time", "fuel_left", "compute_time"]}, "again")
    a, b = flight.fly_case(spec, 0, 1).row, flight.fly_case(spec, 0, 1).row
    assert same_rows([a], [b])  # conftest.same_rows: every column but the measured ones, bit for bit
    assert compare_rows(a, {**b, "compute_time": a["compute_time"] + 1.0}, spec.metrics) == []
    assert compare_rows(a, {**b, "fuel_left": a["fuel_left"] + 1.0}, spec.metrics) != []


def test_the_summary_shows_units_and_the_compute_per_flight():
    spec = parse_spec({**HOLD, "metrics": ["hover_time", "fuel_left", "powered_fuel", "compute_time",
                                           "mpc_solve_time_p99"]}, "units")
    rows = [flight.fly_case(spec, 0, i).row for i in range(2)]
    text = format_summary(summarise(rows, spec.metrics))
    for label in ("hover_time [s]", "fuel_left [kg]", "powered_fuel [kg]", "compute_time [s]", "mpc_solve_time_p99 [s]"):
        assert label in text, text
    assert "compute: " in text and "s a flight" in text


# --------------------------------------------------------------------------- spec errors


@pytest.mark.parametrize("change, key", [
    ({"end": {"duration": 60.0, "hover_band": 1.0}}, r"end\.hover_band: only applies to a hover-hold sweep"),
    ({"end": {"duration": 60.0, "hover_hold": -1.0}}, r"end\.hover_hold: must be > 0"),
    ({"end": {"duration": 60.0, "hover_hold": 90.0}}, r"end\.hover_hold: \(90\.0 s\) is longer than end\.duration"),
    ({"end": {"duration": 60.0, "hover_hold": 5.0, "hover_speed": 0.0}}, r"end\.hover_speed: must be > 0"),
    ({"end": {"duration": 60.0, "hover_hold": 5.0, "land": True}}, r"end\.hover_hold: a sweep is judged either"),
    ({"end": {"duration": 60.0, "hover_hld": 5.0}}, r"end\.hover_hld: unknown key"),
    ({"dispersions": {"thruster_cant_error": {"uniform": {"min": 0.0, "max": 2.0}}}},
     r"dispersions\.thruster_cant_error: a cant error must stay under pi/2"),
    ({"dispersions": {"density_error": {"uniform": {"min": -1.2, "max": 0.3}}}},
     r"dispersions\.density_error: relative error must stay above -1"),
    ({"dispersions": {"orbit_phase": {"normal": {"mean": 0.0, "std": -1.0}}}},
     r"dispersions\.orbit_phase\.normal\.std: a standard deviation must be >= 0"),
    ({"dispersions": {"orbit_altitude": {"uniform": {"min": 10.0, "max": -10.0}}}},
     r"dispersions\.orbit_altitude\.uniform\.min: min \(10\.0\) is greater than max"),
    ({"metrics": ["hover_time", "compute_tme"]}, r"metrics\[1\]: unknown metric 'compute_tme'"),
])
def test_bad_de_orbit_keys_are_named(change, key):
    with pytest.raises(SweepSpecError, match=rf"bad\.yaml: {key}"):
        parse_spec({**ORBIT, **change}, "bad.yaml")


def test_shipped_de_orbit_sweeps_compare_both_laws_over_200_flights():
    from pathlib import Path

    from lander_tools.sweep.spec import load_spec

    root = Path(__file__).resolve().parents[2] / "sweeps"
    for name, scene in (("deorbit.yaml", "deorbit"), ("deorbit-200km.yaml", "deorbit-200km")):
        spec = load_spec(root / name)
        assert spec.scene == scene and spec.flights >= 200 and spec.end.hover_hold == 30.0
        assert [(c.name, c.label) for c in spec.controllers] == [("deorbit", "scheduled"), ("deorbit-mpc", "mpc")]
        d = spec.dispersions
        assert (d.orbit_altitude.a, d.orbit_altitude.b) == (-10000.0, 10000.0)
        assert (d.density_error.a, d.density_error.b) == (-0.3, 0.3) and (d.thrust_error.a, d.thrust_error.b) == (-0.03, 0.03)
        assert d.thruster_cant_error.b == 0.00873 and d.orbit_phase.b == pytest.approx(2.0 * math.pi)
        assert d.mass_error is not None and d.wind_mean is not None and d.wind_gust is not None
        assert "compute_time" in spec.metrics and "powered_fuel" in spec.metrics
        assert "fuel_ratio" in spec.metrics and "powered_optimum" in spec.metrics
        assert "fuel_ratio_balanced" in spec.metrics and "powered_optimum_balanced" in spec.metrics


# --------------------------------------------------------------------------- the fuel yardstick


def test_the_fuel_ratio_is_measured_against_the_optimum_from_the_flights_own_handover_state():
    """``powered_optimum`` solves from the state, vehicle and flown atmosphere of the flight; 30 nodes
    agree with the 60 of the bench to ~1e-6 of the fuel from the common handover case (O(h^2) of a
    piecewise-constant thrust; a golden-section final time to 1e-3 s is flat to first order), asserted
    to the optimum's own 1e-3. ``fuel_ratio`` counts from the handover to the first instant in the hover
    band over it; neither is compared through ROS. A steady wind is the flown scene's."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from handover_case import handover_sim

    from lander_autopilot.controllers.deorbit_mpc import handover_problem
    from lander_autopilot.guidance.fuel_optimal import solve
    from lander_tools.sweep.metrics import Samples, evaluate
    from lander_tools.sweep.spec import CORE_ONLY_METRICS

    sc, sim = handover_sim()
    s = sim.state()
    handover = (s.r_W.copy(), s.v_W.copy(), float(s.fuel), True)
    rho0 = sim.dynamics.atmosphere.surface_density
    best = solve(handover_problem(sc.vehicle, s.r_W, s.v_W, s.fuel, 500.0)[0], steps=60, t_tol=1e-4).fuel
    assert flight.powered_optimum(sim, handover, 500.0) == pytest.approx(best, rel=1e-3)
    # a denser flown atmosphere brakes more for free: its own optimum, not the nominal one
    sim.dynamics.atmosphere = dataclasses.replace(sim.dynamics.atmosphere, surface_density=1.3 * rho0)
    dense = flight.powered_optimum(sim, handover, 500.0)
    expect = solve(handover_problem(sc.vehicle, s.r_W, s.v_W, s.fuel, 500.0, surface_density=1.3 * rho0)[0],
                   steps=60, t_tol=1e-4).fuel
    assert dense == pytest.approx(expect, rel=1e-3) and dense < best * (1 - 1e-2)
    # and the scene's steady wind: the optimum with that wind in its drag
    wind_W = np.array([0.0, 8.0, -6.0])  # 10 m/s across the handover's vertical (world x there)
    sim.scene = dataclasses.replace(sim.scene, wind_W=tuple(wind_W))
    windy = flight.powered_optimum(sim, handover, 500.0)
    expect = solve(handover_problem(sc.vehicle, s.r_W, s.v_W, s.fuel, 500.0, surface_density=1.3 * rho0,
                                    wind_W=wind_W)[0], steps=60, t_tol=1e-4).fuel
    # A crosswind costs little under the chute (~0.1-0.3 % here: it tilts the airflow, hardly its
    # size); 30 against 60 nodes agree to ~1e-6, so the solve with the wind is told from the one without.
    assert abs(windy - expect) < 0.2 * abs(windy - dense)

    # The balanced yardstick: the nominal lander's thrusters are symmetric, so the thrust with no torque
    # is every thruster flat out and the two optima are one. One thruster 3 % weak: full throttle on all
    # four is a torque, the balanced bound is lower, and its optimum (a longer burn) needs more fuel.
    assert flight.powered_optimum(sim, handover, 500.0, balanced=True) == pytest.approx(windy, rel=1e-9)
    ts = list(sim.scene.vehicle.thrusters)
    ts[0] = dataclasses.replace(ts[0], max_thrust=0.97 * ts[0].max_thrust)
    weak = dataclasses.replace(sim.scene.vehicle, thrusters=tuple(ts))
    sim.scene = dataclasses.replace(sim.scene, vehicle=weak)
    nameplate = flight.powered_optimum(sim, handover, 500.0)
    balanced = flight.powered_optimum(sim, handover, 500.0, balanced=True)
    expect = solve(handover_problem(weak, s.r_W, s.v_W, s.fuel, 500.0, surface_density=1.3 * rho0, wind_W=wind_W,
                                    balanced=True)[0], steps=60, t_tol=1e-4).fuel
    assert balanced == pytest.approx(expect, rel=1e-3) and balanced > nameplate * (1 + 1e-3)

    samples = Samples(t=np.array([0.0, 0.1]), altitude_error=np.zeros(2), tilt=np.zeros(2), body_rate=np.zeros(2),
                      fuel_start=70.0, fuel_end=50.0, saturated_updates=0, period=0.1, touchdown_speed=math.nan,
                      terminal="ok", t_change=0.0, speed=np.zeros(2),
                      mode_fuel={"powered-descent": 67.0, "hover": 55.0}, powered_optimum=11.5, band_fuel=54.5)
    spec = parse_spec({**HOLD, "metrics": ["powered_fuel", "powered_optimum", "fuel_ratio"]}, "ratio")
    _, _, m = evaluate(samples, spec.end)
    # the ratio counts to the band (the optimum's end), not to the hover mode
    assert m["powered_fuel"] == 12.0 and m["powered_optimum"] == 11.5 and m["fuel_ratio"] == 12.5 / 11.5
    assert set(CORE_ONLY_METRICS) == {"powered_optimum", "fuel_ratio", "powered_optimum_balanced", "fuel_ratio_balanced"}
    samples.powered_optimum_balanced = 11.9
    _, _, m = evaluate(samples, spec.end)
    assert m["powered_optimum_balanced"] == 11.9 and m["fuel_ratio_balanced"] == 12.5 / 11.9
    row = {"index": 0, "controller": "x", "outcome": "hovered", "powered_fuel": 12.0, "powered_optimum": 11.5,
           "fuel_ratio": 12.0 / 11.5}
    assert compare_rows(row, {**row, "powered_optimum": math.nan, "fuel_ratio": math.nan}, spec.metrics) == []


def test_the_band_is_entered_within_the_period_not_at_its_end():
    """The fuel at the band's entry: the throttles are held over a period, so the fuel is linear in
    time between two control instants; the crossing is the later of the altitude's (linear) and the
    speed's (its magnitude taken as linear: at or after the true crossing), never before the true one."""
    band, limit = 2.0, 0.2
    # the speed alone crosses, 4/5 of the way: 0.6 -> 0.1 m/s, 10.0 -> 9.8 kg
    assert band_entry_fuel(BandSample(0.5, 0.6, 10.0), BandSample(0.4, 0.1, 9.8), band, limit) == pytest.approx(9.84)
    # the altitude alone, from above and from below (half way to the band's edge), and both: the later one
    assert band_entry_fuel(BandSample(3.0, 0.1, 10.0), BandSample(1.0, 0.1, 9.8), band, limit) == pytest.approx(9.9)
    assert band_entry_fuel(BandSample(-2.5, 0.1, 10.0), BandSample(-1.5, 0.1, 9.8), band, limit) == pytest.approx(9.9)
    assert band_entry_fuel(BandSample(3.0, 0.6, 10.0), BandSample(1.0, 0.1, 9.8), band, limit) == pytest.approx(9.84)
    # no instant before (the first one looked at), or already in the band: the instant's own fuel
    assert band_entry_fuel(None, BandSample(0.4, 0.1, 9.8), band, limit) == 9.8
    # the speed's crossing taken on |v| linear is at or after the true one, along any linear velocity
    rng = np.random.default_rng(7)
    for _ in range(200):
        v0, v1 = rng.normal(0.0, 1.0, 3), rng.normal(0.0, 0.1, 3)
        v0 *= (0.3 + rng.random()) / np.linalg.norm(v0)
        v1 *= limit * rng.random() / np.linalg.norm(v1)
        s_lin = (band_entry_fuel(BandSample(0.0, float(np.linalg.norm(v0)), 1.0), BandSample(0.0, float(np.linalg.norm(v1)), 0.0),
                                 band, limit))
        s_lin = 1.0 - s_lin  # fuel 1 -> 0 over the period: the fraction of it
        s = np.linspace(0.0, 1.0, 2001)
        speed = np.linalg.norm(v0[None, :] + s[:, None] * (v1 - v0)[None, :], axis=1)
        s_true = s[np.argmax(speed <= limit)]
        assert s_true <= s_lin + 5e-4  # the grid's half step
