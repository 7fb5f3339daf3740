"""Scene keys that carry a sweep case: true-vehicle scales and scheduled thruster failures."""
from __future__ import annotations

import numpy as np
import pytest

from lander_sim.scenes import SceneError, load_scene, parse_scene
from lander_sim.simulation import Simulation

BASE = {"vehicle": {"preset": "lander"}, "initial": {"position_W": [0, -3396200.0 - 500.0, 0]}, "dt": 0.1,
        "models": {"gravity": {"kind": "inverse-square"}, "thrusters": {}}}


def scene(**vehicle):
    return parse_scene({**BASE, "vehicle": {"preset": "lander", **vehicle}}, "v.yaml")


def test_scales_change_exactly_the_true_vehicle():
    nominal, s = scene(), scene(dry_mass_scale=1.05, inertia_scale=0.9, thrust_scale=[1.0, 0.5, 1.0, 2.0])
    assert s.vehicle.dry_mass == nominal.vehicle.dry_mass * 1.05
    assert np.array_equal(s.vehicle.gyration_sq, np.multiply(nominal.vehicle.gyration_sq, 0.9))
    assert [t.max_thrust for t in s.vehicle.thrusters] == [t.max_thrust * k for t, k in
                                                           zip(nominal.vehicle.thrusters, (1.0, 0.5, 1.0, 2.0))]


@pytest.mark.parametrize("vehicle, key", [
    ({"dry_mass_scale": 0.0}, "vehicle.dry_mass_scale"),
    ({"inertia_scale": -1.0}, "vehicle.inertia_scale"),
    ({"thrust_scale": [1.0, 1.0]}, "vehicle.thrust_scale"),
    ({"thrust_scale": [1.0, 1.0, 0.0, 1.0]}, r"vehicle.thrust_scale\[2\]"),
    ({"failures": [{"thruster": 4, "time": 1.0}]}, r"vehicle.failures\[0\].thruster"),
    ({"failures": [{"thruster": 1, "time": -1.0}]}, r"vehicle.failures\[0\].time"),
    ({"failures": [{"thruster": 1, "time": 1.0}, {"thruster": 1, "time": 2.0}]}, r"vehicle.failures\[1\].thruster"),
    ({"failures": [{"thruster": 1}]}, r"vehicle.failures\[0\].time"),
    ({"mass_scale": 1.0}, "vehicle.mass_scale"),
])
def test_bad_vehicle_keys_are_named(vehicle, key):
    with pytest.raises(SceneError, match=rf"v\.yaml: {key}"):
        scene(**vehicle)


def test_a_failed_thruster_stops_at_its_time_on_both_paths():
    # Thruster 2 fails at 1.05 s: the first step starting at or after it is step 11 (t = 1.1 s).
    # Fuel burn is linear in the throttles: 4 x 0.5 kg/s x 0.5 for 1.1 s, then 3 of them, exactly.
    for fast in (True, False):
        sim = Simulation(scene(failures=[{"thruster": 2, "time": 1.05}]), use_fast_path=fast)
        fuel0 = sim.state().fuel
        sim.set_throttles([0.5] * 4)
        sim.step(11)
        assert sim.failed_thrusters == () and sim.throttles[2] == 0.5
        sim.step(9)
        assert sim.failed_thrusters == (2,) and sim.throttles[2] == 0.0
        sim.set_throttles([0.5] * 4)  # the command no longer reaches it
        assert sim.throttles[2] == 0.0
        used = fuel0 - sim.state().fuel
        # Verlet integrates the constant burn rate exactly; 1e-12 covers summing 20 steps.
        assert used == pytest.approx(4 * 0.25 * 1.1 + 3 * 0.25 * 0.9, rel=1e-12), fast
        sim.reset()
        assert sim.failed_thrusters == ()


def test_hover_scene_still_loads_with_its_older_wind_key():
    assert load_scene("hover").wind_W == (0.0, 0.0, 0.0)
