"""The de-orbit laws learn the air's density while coasting through the entry, and the chute's
predicted drag uses it (+30 % of air tears the canopy off at 0.9 of its modelled limit).

Core-only: scene ``deorbit-200km`` started inside the atmosphere at 22 km, 500 m/s, flight-path
angle -12 deg, thrust axis retrograde, in the flown atmosphere of a sweep case with the density
error fixed (``dispersions.density_error``: uniform on [e, e]), the law in its entry phase.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.deorbit import Phase, thrust_axis_attitude
from lander_autopilot.controllers.registry import make_controller
from lander_sim.physics import constants as c
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.spec import parse_spec


def _entry_sim(error: float) -> tuple[object, Simulation]:
    spec = parse_spec({"name": "air", "scene": "deorbit-200km", "controllers": ["deorbit"], "flights": 1, "seed": 1,
                       "end": {"duration": 60.0},
                       "dispersions": {"density_error": {"uniform": {"min": error, "max": error}}}}, "air")
    scene0 = nominal_scene(spec)
    sc = flown_scene(spec, draw_case(spec, 0, scene0.vehicle.n_thrusters))
    y = sc.initial_state.copy()
    gamma = math.radians(-12.0)
    y[0:3] = (c.MARS_RADIUS + 22_000.0, 0.0, 0.0)
    y[3:6] = (500.0 * math.sin(gamma), 500.0 * math.cos(gamma), 0.0)
    y[6:10] = thrust_axis_attitude(y[6:10], -y[3:6] / np.linalg.norm(y[3:6]))
    y[10:13] = 0.0
    return scene0, Simulation(dataclasses.replace(sc, initial_state=y))


@pytest.mark.parametrize("error", [0.3, -0.3, 0.0])
def test_the_entry_learns_the_density_the_air_really_has(error):
    scene0, sim = _entry_sim(error)
    ctrl = make_controller("deorbit", scene0.vehicle)
    ctrl.start_in(Phase.ENTRY)
    demand = Demand(altitude=500.0)
    n_sub = round(0.1 / sim.dt)
    scale = None
    while sim.t < 20.0 - 1e-9:
        out = ctrl.update(sim.t, sim.state(), demand)
        if ctrl.phase is not Phase.ENTRY:  # the chute asked for: what was learnt is what it used
            break
        scale = ctrl.descent.law.density_scale
        sim.set_throttles(out.throttles)
        sim.step(n_sub)
    assert sim.t >= 12.0  # coasted long enough for the filter (see below)
    # The drag is the sphere's, the model's to the bit but for the density; the measurement is a
    # difference of velocities over 0.1 s (the mean deceleration over the period, against the model's
    # at its end: ~1e-3 relative), filtered with 2 s over >= 12 s (e^-6 of the start's error left).
    assert scale == pytest.approx(1.0 + error, rel=5e-3)


def test_the_chute_waits_for_the_drag_the_denser_air_will_give():
    """At the speed where the modelled drag is 0.85 of the canopy's limit (under the 0.9 margin),
    +30 % of air would give 1.1 of it: the learnt density holds the request back."""
    scene0, _ = _entry_sim(0.0)
    descent = make_controller("deorbit", scene0.vehicle).descent
    h = 5000.0
    from lander_autopilot.controllers.landing import CHUTE_DRAG_K
    from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE

    speed = math.sqrt(0.85 * c.PARACHUTE_MAX_DRAG / (CHUTE_DRAG_K * MARS_ATMOSPHERE.density(h)))
    assert speed < descent.law.chute_margin * c.PARACHUTE_MAX_SPEED
    assert descent.law.chute_request(h, -speed, speed) is not None
    descent.reset()
    descent.law.density_scale = 1.3
    assert descent.law.chute_request(h, -speed, speed) is None
