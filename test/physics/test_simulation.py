"""The Simulation object: inputs, events, ground contact, stabiliser, snapshots."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_sim.errors import InputError
from lander_sim.physics import constants as c
from lander_sim.physics import rotation
from lander_sim.physics.events import EventKind, Phase
from lander_sim.physics.models import ChuteStatus
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation


def near_ground(v_down: float, height: float = 0.05):
    """Scene 1 moved to ``height`` above touchdown, falling at ``v_down`` m/s, no stabiliser."""
    s = load_scene("descent-10km")
    y = s.initial_state.copy()
    y[0:3] = [0.0, -(c.MARS_RADIUS + 0.5 + height), 0.0]
    y[3:6] = [0.0, v_down, 0.0]  # towards the centre: +y from the -y axis
    return dataclasses.replace(s, initial_state=y, stabiliser=False)


@pytest.mark.parametrize("bad, match", [
    ([0.5, 0.5, 0.5], r"throttles must have 4 values"),
    ([0.5, float("nan"), 0.5, 0.5], r"throttles\[1\] must be a finite number in \[0, 1\], got nan"),
    ([0.5, 0.5, 1.5, 0.5], r"throttles\[2\] must be a finite number in \[0, 1\], got 1.5"),
    ([0.5, 0.5, 0.5, -0.1], r"throttles\[3\] .* got -0.1"),
    ("full", r"throttles must be a sequence of numbers"),
])
def test_bad_throttles_are_rejected_named_counted_and_leave_state_alone(bad, match):
    sim = Simulation(load_scene("hover"))
    sim.set_throttles([0.1, 0.2, 0.3, 0.4])
    before = (sim.y.copy(), sim.throttles)
    with pytest.raises(InputError, match=match):
        sim.set_throttles(bad)
    assert np.array_equal(sim.y, before[0]) and np.array_equal(sim.throttles, before[1])
    assert sim.rejected["throttles"] == 1


def test_bad_wind_stabiliser_and_missing_parachute_are_rejected():
    sim = Simulation(load_scene("free-spin"))
    with pytest.raises(InputError, match=r"wind must be 3 finite numbers"):
        sim.set_wind([1.0, float("inf"), 0.0])
    with pytest.raises(InputError, match=r"wind must be 3"):
        sim.set_wind([1.0, 2.0])
    with pytest.raises(InputError, match=r"stabiliser must be true or false, got 'yes'"):
        sim.set_stabiliser("yes")  # type: ignore[arg-type]  # the wrong type is the test
    with pytest.raises(InputError, match=r"has no parachute"):
        sim.deploy_parachute()
    assert sim.rejected == {"throttles": 0, "wind": 2, "parachute": 1, "stabiliser": 1}
    assert issubclass(InputError, ValueError)


def test_gentle_touchdown_is_located_inside_the_step_and_freezes_the_state():
    dt, v, h = 0.1, 0.5, 0.05
    sim = Simulation(near_ground(v, h), dt=dt)
    sim.step(5)
    assert sim.phase is Phase.LANDED
    (ev,) = sim.drain_events()
    g = c.SURFACE_GRAVITY
    t_exact = (-v + math.sqrt(v * v + 2 * g * h)) / g
    # Linear interpolation inside the step: position error <= g dt^2 / 8, time error that over v.
    assert abs(ev.values["t_impact"] - t_exact) < g * dt * dt / 8 / v
    assert abs(np.linalg.norm(sim.y[0:3]) - (c.MARS_RADIUS + 0.5)) < 1e-6
    frozen = sim.y.copy()
    sim.set_throttles([1, 1, 1, 1])  # accepted, but forced to 0 on the ground
    sim.step(10)
    assert np.array_equal(sim.y, frozen) and not sim.throttles.any()
    assert math.isclose(sim.t, 1.5)


def test_fast_touchdown_is_a_crash():
    sim = Simulation(near_ground(5.0))
    sim.step(3)
    assert sim.phase is Phase.CRASHED
    (ev,) = sim.drain_events()
    assert ev.kind is EventKind.CRASHED and ev.values["descent_rate"] > 1.0


def test_stabiliser_points_body_z_up_and_zeroes_omega_keeping_yaw():
    s = load_scene("tumbling-descent")
    sim = Simulation(s)
    sim.set_stabiliser(True)
    sim.step()
    R = rotation.quat_to_matrix(sim.y[6:10])
    up = sim.y[0:3] / np.linalg.norm(sim.y[0:3])
    assert np.allclose(R[2], up, atol=1e-12) and not sim.y[10:13].any()
    # Already upright: left exactly as it was (yaw kept).
    q = sim.y[6:10].copy()
    sim.step()
    assert np.allclose(sim.y[6:10], q, atol=1e-12)


def test_fuel_runs_out_then_throttles_are_forced_to_zero():
    s = load_scene("hover")
    y = s.initial_state.copy()
    y[13] = 0.01  # 4 thrusters at full throttle burn 2 kg/s: empty within the first step
    sim = Simulation(dataclasses.replace(s, initial_state=y))
    sim.set_throttles([1, 1, 1, 1])
    sim.step()
    assert sim.y[13] == 0.0 and not sim.throttles.any()
    assert [e.kind for e in sim.drain_events()] == [EventKind.FUEL_EMPTY]


def test_parachute_deploys_and_is_torn_off_when_overloaded():
    sim = Simulation(load_scene("descent-10km"))
    sim.advance_to(20.0)
    assert sim.deploy_parachute() is ChuteStatus.DEPLOYED
    v0 = abs(sim.derived().climb_rate)
    sim.step(20)
    assert abs(sim.derived().climb_rate) < v0  # the chute brakes
    # A gale: 1000 m/s of wind is ~3.3e5 N on the canopy, far over 20 kN.
    sim.set_wind([1000.0, 0.0, 0.0])
    sim.step()
    assert sim.parachute is not None and sim.parachute.status is ChuteStatus.LOST
    kinds = [e.kind for e in sim.drain_events()]
    assert kinds == [EventKind.PARACHUTE_DEPLOYED, EventKind.PARACHUTE_LOST]


def test_snapshot_restore_is_bit_exact():
    sim = Simulation(load_scene("tumbling-descent-mesh"))
    sim.set_throttles([0.3, 0.1, 0.0, 0.2])
    sim.set_wind([5.0, 0.0, -2.0])
    sim.step(30)
    snap = sim.snapshot()
    sim.step(50)
    a = (sim.y.copy(), sim.t)
    sim.set_throttles([1, 1, 1, 1])
    sim.set_wind([0, 0, 0])
    sim.restore(snap)
    sim.step(50)
    assert np.array_equal(sim.y, a[0]) and sim.t == a[1]


def test_reset_and_derived_quantities():
    sim = Simulation(load_scene("circular-orbit"))
    d = sim.derived()
    assert math.isclose(d.altitude, 0.2 * c.MARS_RADIUS, rel_tol=1e-12)
    assert abs(d.climb_rate) < 1e-9 and math.isclose(d.ground_speed, 3247.087385863725)
    # Circular orbit: E = -GM m / (2 r) (virial), rotational energy zero at rest.
    assert math.isclose(d.energy, -c.GM_MARS * 200.0 / (2 * 1.2 * c.MARS_RADIUS), rel_tol=1e-9)
    sim.step(10)
    sim.reset()
    assert sim.t == 0.0 and np.array_equal(sim.y, sim.scene.initial_state)


def test_fast_kernel_and_numpy_path_fly_the_same_descent():
    """The compiled kernel is an optimisation, not a different model: a whole powered descent
    (throttle changes, drag, fuel burn, touchdown interpolation) must match the numpy path.

    Per step the two agree to ~1e-14 relative (same operations, different rounding order);
    over a non-chaotic descent of a few thousand steps the differences grow at most linearly,
    so 1e-9 relative on the touchdown state and time is a generous but meaningful bound.
    """
    from lander_sim import fast

    if not fast.HAVE_NUMBA:
        pytest.skip("numba is not installed: only the numpy path exists")
    scene = load_scene("descent-10km")
    runs = []
    for use_fast in (True, False):
        sim = Simulation(scene, dt=0.05, use_fast_path=use_fast)
        sim.set_stabiliser(False)  # the kernel has no stabiliser; the aid would hide the rotation anyway
        assert sim.fast_path is use_fast
        sim.set_throttles([0.3, 0.3, 0.3, 0.3])
        sim.step(400)
        sim.set_throttles([0.0, 0.2, 0.0, 0.2])  # a torque too, so rotation is exercised
        sim.step(100)
        sim.set_throttles([0.1, 0.1, 0.1, 0.1])
        while sim.phase is Phase.FLYING and sim.t < 600.0:
            sim.step(100)
        events = [e for e in sim.drain_events() if e.kind in (EventKind.LANDED, EventKind.CRASHED)]
        runs.append((sim.y.copy(), events[0].values["t_impact"], sim.phase))
    (y_fast, t_fast, ph_fast), (y_np, t_np, ph_np) = runs
    assert ph_fast is ph_np
    assert t_fast == pytest.approx(t_np, rel=1e-9)
    np.testing.assert_allclose(y_fast[0:3], y_np[0:3], rtol=1e-9)
    np.testing.assert_allclose(y_fast[6:14], y_np[6:14], rtol=1e-9, atol=1e-9)
