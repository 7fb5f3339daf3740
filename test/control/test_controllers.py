"""Controller plug-ins: interface, registry, parameter and demand validation, law signs."""
from __future__ import annotations

import math
import sys
import textwrap

import numpy as np
import pytest

from lander_autopilot.controllers import (
    ControllerError,
    Demand,
    DemandError,
    available_controllers,
    make_controller,
)
from lander_autopilot.design.altitude import hover_throttle, vertical_thrust
from lander_autopilot.design.attitude import attitude_model
from lander_autopilot.design.gains import closed_loop_poles
from lander_sim.physics import rotation
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.state import StateView
from lander_sim.scenes.vehicles import lander

UPRIGHT = (0.0, math.pi / 2, 0.0)
BUILTINS = ["altitude", "altitude-integral", "altitude-p", "attitude-euler", "attitude-quaternion",
            "baseline", "combined", "combined-quaternion", "integral", "lqr"]


@pytest.fixture(scope="module")
def canted():
    return lander("canted")


def _state(alt=500.0, climb=0.0, E=UPRIGHT, omega=(0.0, 0.0, 0.0), fuel=100.0) -> StateView:
    """A state on the world -y axis (radial = -y)."""
    E = np.asarray(E, dtype=float)
    return StateView(
        t=0.0,
        r_W=np.array([0.0, -(MARS_RADIUS + alt), 0.0]),
        v_W=np.array([0.0, -climb, 0.0]),
        q=rotation.euler_to_quat(E),
        euler=E,
        omega_B=np.asarray(omega, dtype=float),
        fuel=fuel,
    )


def test_all_builtins_are_listed_and_fly_one_step(canted):
    assert set(BUILTINS) <= set(available_controllers())
    for name in BUILTINS:
        c = make_controller(name, canted)
        out = c.update(0.0, _state(), Demand())
        assert out.throttles.shape == (4,) and np.all((out.throttles >= 0) & (out.throttles <= 1))
        c.reset()


@pytest.mark.parametrize("name", ["altitude", "combined", "combined-quaternion", "integral", "lqr"])
def test_laws_give_the_eq_14_hover_throttle_at_equilibrium(canted, name):
    # At the demand, at rest, upright: the feedback terms vanish and every thruster gives
    # t_e = GMm/(Tv z^2) (eq 14, with the canted Tv). Exact to rounding.
    out = make_controller(name, canted).update(0.0, _state(), Demand())
    np.testing.assert_allclose(out.throttles, hover_throttle(canted, 100.0, MARS_RADIUS + 500.0), rtol=1e-12)
    assert not out.saturated


def test_baseline_is_the_extended_programs_autopilot():
    # t = t_e + 0.1 (500 - h), t_e = GMm/(|r|^2 N Tmax); 3 m low -> +0.3 on every thruster.
    v = lander("standard")
    out = make_controller("baseline", v).update(0.0, _state(alt=497.0, climb=-1.0), Demand())
    t_e = hover_throttle(v, 100.0, MARS_RADIUS + 497.0)  # Tv = N Tmax for vertical thrusters
    np.testing.assert_allclose(out.throttles, t_e + 0.3, rtol=1e-12)


def _feedback_jacobian(ctrl, demand, h=1e-6):
    """d(throttles)/d[E, omega] at upright rest, by central differences of the law."""
    J = np.zeros((4, 6))
    x0 = np.r_[UPRIGHT, 0.0, 0.0, 0.0]
    for j in range(6):
        d = np.zeros(6)
        d[j] = h
        up = ctrl.command(0.0, _state(E=x0[:3] + d[:3], omega=d[3:]), demand)
        dn = ctrl.command(0.0, _state(E=x0[:3] - d[:3], omega=-d[3:]), demand)
        J[:, j] = (up - dn) / (2 * h)
    return J


@pytest.mark.parametrize("name", ["attitude-euler", "attitude-quaternion"])
def test_attitude_laws_close_the_loop_with_the_designed_poles(canted, name):
    # The sign convention (u = -K (x - x_e)) checked on the law itself: its Jacobian F w.r.t.
    # [E, omega] gives x' = (A + B F) x, whose eigenvalues must be the designed -1 (x6).
    # For the quaternion law at upright, 2 v_err = J^-1 dE to first order, so the same holds.
    # FD of a linear law is exact to rounding; repeated poles spread as eps^(1/2) -> 1e-5.
    ctrl = make_controller(name, canted)
    m = attitude_model(canted, 100.0)
    F = _feedback_jacobian(ctrl, Demand())
    poles = closed_loop_poles(m.A, m.B, -F)
    np.testing.assert_allclose(poles, -1.0, atol=1e-5)


def test_altitude_law_gain_is_scheduled_with_mass(canted):
    # B = Tv/m: the law scales K by m/m_d, so the per-metre acceleration p1 p2 = 0.99 stays.
    c = make_controller("altitude", canted)
    for fuel in (100.0, 20.0):
        m = canted.mass(fuel)
        t0 = c.update(0.0, _state(fuel=fuel), Demand()).throttles[0]
        t1 = c.update(0.0, _state(alt=499.0, fuel=fuel), Demand()).throttles[0]
        # 1 m low changes also t_e by 2 g / z per metre (~1e-6 relative): negligible at 1e-5.
        assert (t1 - t0) * vertical_thrust(canted) / m == pytest.approx(0.99, rel=1e-5)


def test_saturation_is_reported_and_throttles_clipped(canted):
    out = make_controller("combined", canted).update(0.0, _state(alt=300.0), Demand())
    assert out.saturated and np.all(out.throttles == 1.0) and np.all(out.unclipped > 1.0)
    out = make_controller("altitude", canted).update(0.0, _state(alt=900.0), Demand())
    assert out.saturated and np.all(out.throttles == 0.0)


def test_combined_law_keeps_attitude_authority_when_saturating(canted):
    # Far below the demand and tilted: the plain sum would put all four at 1 (no torque). The
    # mixer gives up collective throttle instead, so the differential throttles survive.
    # Exactly: throttles = c + u_attitude with the collective c moved into range.
    c = make_controller("combined", canted)
    s = _state(alt=300.0, E=(0.0, math.pi / 2 + 0.3, 0.0))
    out = c.update(0.0, s, Demand())
    u_att = c.attitude.command(0.0, s, Demand())
    assert out.saturated and np.all(out.unclipped > 1.0)
    assert out.throttles.max() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(out.throttles - out.throttles.max(), u_att - u_att.max(), atol=1e-12)


def test_integral_law_accumulates_and_resets(canted):
    c = make_controller("altitude-integral", canted)
    low = _state(alt=499.0)
    first = c.update(0.0, low, Demand()).throttles[0]
    c.update(1.0, low, Demand())
    later = c.update(2.0, low, Demand()).throttles[0]
    assert later > first  # integral of a negative error raises the throttle
    c.reset()
    assert c.update(3.0, low, Demand()).throttles[0] == pytest.approx(first, rel=1e-12)


# --- errors -------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"altitude": float("nan")}, "finite"),
        ({"altitude": -5.0}, "below the ground"),
        ({"altitude": float("inf")}, "finite"),
        ({"altitude": "high"}, "number"),
        ({"attitude": (0.0, 1.0)}, "attitude must be 3 finite numbers"),
        ({"omega_B": (0.0, float("nan"), 0.0)}, "omega_B must be 3 finite"),
    ],
)
def test_bad_demand_is_rejected_with_the_field_named(kwargs, match):
    with pytest.raises(DemandError, match=match):
        Demand(**kwargs)
    assert issubclass(DemandError, ValueError)


def test_unknown_controller_lists_the_valid_names(canted):
    with pytest.raises(ControllerError, match=r"unknown controller 'pid'; available: .*combined"):
        make_controller("pid", canted)


@pytest.mark.parametrize(
    "name, params, match",
    [
        ("attitude-euler", {"K": np.zeros((3, 6))}, r"K: expected shape \(4, 6\), got \(3, 6\)"),
        ("altitude", {"K": [1.0, 2.0, 3.0]}, r"K: expected shape \(1, 2\)"),
        ("combined", {"K_attitude": np.zeros((4, 5))}, r"K: expected shape \(4, 6\)"),
        ("altitude", {"poles": [-1.0]}, "poles: expected 2 poles"),
        ("altitude", {"poles": [1.0, -1.0]}, "negative real part"),
        ("altitude", {"gain": 3}, "unknown parameter.*gain.*accepted: K, design_fuel, p_only, poles"),
        ("lqr", {"Q_attitude": [1.0] * 5}, r"Q_attitude: expected shape \(6,\)"),
        ("attitude-euler", {"design_attitude": (0.0, 0.0, 0.0)}, "singularity"),
    ],
)
def test_bad_parameters_are_rejected_naming_the_parameter(canted, name, params, match):
    with pytest.raises(ControllerError, match=match):
        make_controller(name, canted, **params)


def test_lqr_on_vertical_thrusters_fails_clearly():
    with pytest.raises(ControllerError, match="lqr.*stabilisable"):
        make_controller("lqr", lander("standard"))


def test_given_gain_is_used_verbatim(canted):
    K = np.arange(24.0).reshape(4, 6) * 1e-3
    c = make_controller("attitude-euler", canted, K=K)
    e = np.array([0.0, 0.01, 0.0, 0.0, 0.0, 0.0])
    out = c.command(0.0, _state(E=np.array(UPRIGHT) + e[:3]), Demand())
    np.testing.assert_allclose(out, -K @ e, rtol=1e-12)


# --- third-party plug-in ---------------------------------------------------------


def test_third_party_controller_registers_through_an_entry_point(tmp_path, monkeypatch, canted):
    # A minimal installed distribution: a module and a dist-info with entry_points.txt, found
    # by importlib.metadata on sys.path exactly as a pip-installed plug-in would be.
    (tmp_path / "hover_plugin.py").write_text(textwrap.dedent('''
        import numpy as np
        from lander_autopilot.controllers.base import Controller

        class Constant(Controller):
            name = "constant"
            def __init__(self, vehicle, *, level=0.5):
                super().__init__(vehicle)
                self.level = level
            def command(self, t, state, demand):
                return np.full(self.n_thrusters, self.level)
    '''))
    info = tmp_path / "hover_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hover-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[mars_lander.controllers]\nconstant = hover_plugin:Constant\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "constant" in available_controllers()
    c = make_controller("constant", canted, level=0.25)
    np.testing.assert_array_equal(c.update(0.0, _state(), Demand()).throttles, 0.25)
    with pytest.raises(ControllerError, match="unknown parameter.*colour.*accepted: level"):
        make_controller("constant", canted, colour="red")
    sys.modules.pop("hover_plugin", None)
