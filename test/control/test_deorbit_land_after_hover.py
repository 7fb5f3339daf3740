"""The de-orbit laws' own landing once the hover has been held ``land_after_hover`` seconds, core-only
(docs/deorbit.md, "Phases"): flown from the common handover case (test/handover_case.py) under the
open chute, through the powered descent into the 500 m hover, then down with the demand left at
500 m."""
from __future__ import annotations

import numpy as np
import pytest
from handover_case import handover_sim

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.base import ControllerError
from lander_autopilot.controllers.deorbit import Phase
from lander_autopilot.controllers.deorbit.phases import settled
from lander_autopilot.controllers.registry import make_controller
from lander_sim.physics import constants as c

DEMAND = Demand(altitude=500.0)
HOLD = 5.0  # [s] a short hold: the property is the clock, not its length


def _fly(law: str, until: float, **params):
    """Fly ``law`` (``params``) from the handover case at demand 500 m to ``until`` [s] or an end
    event. Returns (controller, [(t, phase, state, throttles)], end event or None)."""
    sc, sim = handover_sim()
    ctrl = make_controller(law, sc.vehicle, **params)
    ctrl.start_in(Phase.PARACHUTE, chute_open=True)
    log, end = [], None
    while sim.t < until and end is None:
        s = sim.state()
        out = ctrl.update(sim.t, s, DEMAND)
        log.append((sim.t, ctrl.phase, s, out.throttles.copy()))
        sim.set_throttles(out.throttles)
        sim.step()
        end = next((e for e in sim.drain_events() if e.kind.name in ("CRASHED", "LANDED", "HARD_LANDING")), None)
    return ctrl, log, end


def _first(log, phase):
    return next(i for i, (_, p, _, _) in enumerate(log) if p is phase)


@pytest.mark.parametrize("law", ["deorbit", "deorbit-mpc"])
def test_lands_once_the_hover_is_held_the_time_asked_not_before(law):
    ctrl, log, end = _fly(law, 400.0, land_after_hover=HOLD)
    i_hover, i_land = _first(log, Phase.HOVER), _first(log, Phase.LANDING)
    t_hover, t_land = log[i_hover][0], log[i_land][0]
    # every period from the hover's start to the landing met the capture criterion (the hover held)
    for t, _, s, _ in log[i_hover:i_land + 1]:
        h = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS
        climb = float(s.v_W @ s.r_W) / float(np.linalg.norm(s.r_W))
        assert settled(h - DEMAND.altitude, climb, ctrl.hover_band, ctrl.hover_speed), (t, h, climb)
    # so the clock ran from the hover's first period: the landing at the first period at least HOLD
    # after it, so less than one control period later (1e-9 s: the float sum of the steps)
    dt = log[1][0] - log[0][0]
    assert HOLD <= t_land - t_hover < HOLD + dt + 1e-9, (t_hover, t_land)
    assert all(p is Phase.HOVER for _, p, _, _ in log[i_hover:i_land])
    t, before, after, why = ctrl.log.transitions[-1]
    assert (before, after) == (Phase.HOVER, Phase.LANDING) and t == t_land and "hover held" in why
    assert ctrl.diagnostics()["landing_on_hold"] == 1.0
    # the landing law flew to the ground on demand altitude 0 with the demand left at 500 m: a soft touchdown
    assert end is not None and end.kind.name == "LANDED", end
    assert end.values["descent_rate"] < 1.0


def test_unset_never_lands_and_flies_the_same_bits_as_a_hold_never_reached():
    # none: the hover is held past any hold; a hold longer than the flight changes no throttle
    ctrl, log, end = _fly("deorbit", 120.0)
    assert end is None and log[-1][1] is Phase.HOVER and "land_after_hover" not in ctrl.diagnostics()
    t_hover = log[_first(log, Phase.HOVER)][0]
    assert log[-1][0] - t_hover > 2 * HOLD
    _, log_long, _ = _fly("deorbit", 120.0, land_after_hover=1e6)
    assert len(log_long) == len(log)
    for (t, p, s, u), (t2, p2, s2, u2) in zip(log, log_long):
        assert t == t2 and p is p2 and np.array_equal(u, u2)
        assert np.array_equal(s.r_W, s2.r_W) and np.array_equal(s.v_W, s2.v_W) and s.fuel == s2.fuel


@pytest.mark.parametrize("bad", [0.0, -1.0, "soon"])
def test_a_hold_that_is_not_a_positive_time_is_refused_naming_it(bad):
    sc, _ = handover_sim()
    with pytest.raises(ControllerError, match="land_after_hover"):
        make_controller("deorbit", sc.vehicle, land_after_hover=bad)
