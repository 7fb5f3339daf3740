"""The de-orbit braking limb's drag on a fall through moving air (FallDrag): the still-air closed
form, the ODE it integrates, and Newton's inverse. Core-only, fast."""
from __future__ import annotations

import math

import pytest

from lander_autopilot.controllers.deorbit import FallDrag

CD = 1.3e-3  # [1/m]: ~60 m^2 of 1/2 Cd A, 0.015 kg/m^3, 700 kg
A_B = 5.0  # [m/s^2] thrust deceleration of the limb


def _height_by_rk4(drag: FallDrag, s: float, n: int = 4000) -> float:
    """``int_0^s x / (a_b + D(x)) dx`` by classical RK4 on ``dh/dx`` (an independent quadrature)."""
    f = lambda x: x / (A_B + drag.deceleration(x))  # noqa: E731
    h, dx = 0.0, s / n
    for k in range(n):
        x = k * dx
        h += dx / 6.0 * (f(x) + 4.0 * f(x + 0.5 * dx) + f(x + dx))
    return h


def test_still_air_is_the_closed_form():
    """No wind: D = cd s^2 and the limb is ``v^2 = (a_b / c)(e^{2 c h} - 1)``, the law's still-air curve."""
    drag = FallDrag(CD, 0.0, 0.0)
    assert drag.deceleration(30.0) == pytest.approx(CD * 900.0, rel=1e-15)
    for h_c in (0.5, 10.0, 100.0, 400.0):
        closed = math.sqrt((A_B / CD) * math.expm1(2.0 * CD * h_c))
        assert drag.limb_speed(A_B, h_c) == pytest.approx(closed, rel=1e-9)
        # 8-point Gauss-Legendre: the integrand's poles at +-i sqrt(a_b / c) (~62 m/s) lie near the
        # interval [0, v]; for v ~ 60 m/s the Bernstein ellipse through them has rho ~ 3.7, error ~ rho^-16 ~ 1e-9
        assert drag.stopping_height(A_B, closed) == pytest.approx(h_c, rel=1e-8)


@pytest.mark.parametrize("w_up, w_h", [(4.0, 0.0), (-4.0, 0.0), (3.0, 5.0), (-2.0, 6.0)])
def test_limb_in_a_wind_inverts_the_stopping_height(w_up: float, w_h: float):
    drag = FallDrag(CD, w_up, w_h)
    still = FallDrag(CD, 0.0, 0.0)
    for s in (5.0, 20.0, 40.0):
        # the quadrature against an independent RK4 integration of the same ODE. Updraft: the
        # integrand is analytic, its nearest singularities (u = +-i w_h) off the interval, Gauss's
        # error ~1e-6 of the height at most. Downdraft: the drag changes sign where the fall is as fast
        # as the air (s = -w_up), D is C1 there, not C2, and Gauss converges only as n^-3 across the
        # kink (0.14 mm of 39 m measured at 40 m/s). What the law needs: the limb is re-solved every
        # 0.1 s in a 2 m band, a millimetre is ample.
        tol = 1e-6 * s if w_up >= 0.0 else 1e-3
        assert drag.stopping_height(A_B, s) == pytest.approx(_height_by_rk4(drag, s), abs=tol)
    for h_c in (2.0, 50.0, 300.0):
        v = drag.limb_speed(A_B, h_c)
        assert drag.stopping_height(A_B, v) == pytest.approx(h_c, rel=1e-6)
        # an updraft adds drag through the fall: faster at the same height; a downdraft the opposite
        if w_up > 0.0:
            assert v > still.limb_speed(A_B, h_c)
        elif w_h == 0.0:
            assert v < still.limb_speed(A_B, h_c)
    # no thrust to brake with (the attitude law takes the whole collective): no limb, no division by zero
    assert drag.limb_speed(0.0, 50.0) == 0.0


def test_damping_is_the_drags_derivative():
    drag = FallDrag(CD, 2.5, 4.0)
    for s in (1.0, 10.0, 35.0):
        eps = 1e-4 * s
        fd = (drag.deceleration(s + eps) - drag.deceleration(s - eps)) / (2.0 * eps)
        assert drag.damping(s) == pytest.approx(fd, rel=1e-7)
    # still air: 2 cd s, the law's damping before the fit
    assert FallDrag(CD, 0.0, 0.0).damping(20.0) == pytest.approx(2.0 * CD * 20.0, rel=1e-15)
