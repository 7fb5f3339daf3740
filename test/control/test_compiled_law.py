"""The compiled form of each linear law against its Python ``update()`` on states of real flights.

States come from a core-only flight (Simulation + the Python law at 10 Hz, with a demand step so
the altitude error changes sign, a tilted start so the attitude law works and saturates). At every
control instant both forms see the same state; the compiled throttles must match to 1e-12
(the only difference allowed is the summation order of ``K e``: six terms of size <= 10, so a few
ulps of 1) and the saturation flag exactly. The integral law carries its own state in both forms.
"""
from __future__ import annotations

import numpy as np
import pytest

from lander_autopilot.controllers import Demand, make_controller
from lander_autopilot.controllers.compiled import (
    LawState,
    compiled_form,
    demand_array,
    reference_update,
)
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation

LAWS = ["altitude", "altitude-p", "altitude-integral", "attitude-euler", "attitude-quaternion",
        "combined", "combined-quaternion", "integral", "lqr"]


def _record_and_compare(name: str) -> tuple[int, int]:
    scene = load_scene("hover-canted")
    ctrl = make_controller(name, scene.vehicle)
    law = compiled_form(ctrl)
    assert law is not None, f"{name} has no compiled form"
    sim = Simulation(scene)
    state = LawState()
    before, after = Demand(altitude=500.0), Demand(altitude=460.0)
    d_before = demand_array(before.altitude, before.attitude, before.omega_B)
    d_after = demand_array(after.altitude, after.attitude, after.omega_B)
    sats = compared = 0
    for _ in range(300):
        t = sim.t
        st = sim.state()
        demand, d = (before, d_before) if t < 15.0 else (after, d_after)
        out = ctrl.update(t, st, demand)
        u, sat = reference_update(law, state, t, sim.y, d)
        np.testing.assert_allclose(u, out.throttles, rtol=0.0, atol=1e-12, err_msg=f"{name} at t = {t}")
        assert sat == bool(out.saturated), f"{name} at t = {t}: saturated {sat} vs {out.saturated}"
        sats += sat
        compared += 1
        sim.set_throttles(out.throttles)
        sim.step()
        if sim.phase.name != "FLYING":
            break
    return compared, sats


@pytest.mark.parametrize("name", LAWS)
def test_compiled_law_matches_python_update_on_recorded_states(name):
    compared, sats = _record_and_compare(name)
    assert compared >= 100
    if name in ("combined", "combined-quaternion", "integral"):
        assert sats > 0  # the tilted start saturates: the mixing branch was compared too


def test_laws_that_change_the_law_have_no_compiled_form():
    scene = load_scene("hover-canted")
    gs = make_controller("ground-speed", scene.vehicle)
    assert compiled_form(gs) is None  # overrides command(): flies on the per-flight path
    assert compiled_form(object()) is None  # a plug-in without compiled_form()
