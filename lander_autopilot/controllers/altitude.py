"""Altitude laws: the extended program's baseline, state feedback (eq 18-21) and integral action.

All use one throttle on every thruster. Altitude ``h = |r_W| - R_mars`` and climb rate
``h' = v_W . r_hat`` come from the state; ``z = R_mars + h`` is eq 9's distance from the centre.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from lander_sim.physics.constants import GM_MARS
from lander_sim.physics.constants import MARS_RADIUS as _R
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.altitude import vertical_thrust
from ._params import matrix_param, poles_param, positive_param
from .base import Controller, ControllerError, Demand, altitude_and_climb_rate


def _check_can_hover(vehicle: Vehicle) -> float:
    tv = vertical_thrust(vehicle)
    if tv <= 0.0:
        raise ControllerError(f"vehicle has no upward thrust (T_v = {tv} N): an altitude law cannot work")
    return tv


class BaselineController(Controller):
    """The extended program's own autopilot: ``t = t_e + k_p (z_e - z) + k_d (0 - z')`` on all thrusters.

    ``t_e = G M m / (|r|^2 sum T_max)`` at the current mass and radius; ``k_p = 0.1``, ``k_d = 0``
    by default (P-only: marginally stable, eq 21, so it oscillates; seed 2 task 1).
    """

    name: ClassVar[str] = "baseline"

    def __init__(self, vehicle: Vehicle, *, kp: float = 0.1, kd: float = 0.0) -> None:
        super().__init__(vehicle)
        self.kp = float(matrix_param("kp", kp, ()))
        self.kd = float(matrix_param("kd", kd, ()))
        self._tmax = sum(t.max_thrust for t in vehicle.thrusters if t.enabled)
        if self._tmax <= 0.0:
            raise ControllerError("vehicle has no enabled thruster: the baseline autopilot cannot work")
        self._ones = np.ones(self.n_thrusters)

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        h, hd = altitude_and_climb_rate(state)
        r = h + _R
        t_e = GM_MARS * self.vehicle.mass(state.fuel) / (r * r * self._tmax)
        return (t_e + self.kp * (demand.altitude - h) - self.kd * hd) * self._ones


class AltitudeController(Controller):
    """Altitude state feedback, eq 18: ``t = t_e - K [h - h_e, h']`` with ``K`` from pole placement.

    Designed on eq 16 (``B = T_v / m_d``) at the design fuel. In flight the gain is rescaled by
    ``m / m_d`` and ``t_e`` (eq 14) is evaluated at the current mass and radius, so the closed
    loop keeps the designed poles as fuel burns (``B K`` stays constant).
    Seed 2's poles ``(-0.9, -1.1)`` by default; ``k2 = 0`` gives the P-only law of eq 21.
    """

    name: ClassVar[str] = "altitude"
    #: ``k2 = 0`` unless the ``p_only`` parameter says otherwise.
    p_only_default: ClassVar[bool] = False

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        poles: object = (-0.9, -1.1),
        K: object | None = None,
        design_fuel: float | None = None,
        p_only: bool | None = None,
    ) -> None:
        super().__init__(vehicle)
        self.T_v = _check_can_hover(vehicle)
        fuel = vehicle.fuel_capacity if design_fuel is None else positive_param("design_fuel", design_fuel)
        self.design_mass = vehicle.mass(fuel)
        if K is None:
            from ..design.altitude import altitude_model
            from ..design.gains import place_poles

            model = altitude_model(vehicle, fuel, 0.0)
            K = place_poles(model.A, model.B, poles_param("poles", poles, 2)).K
        self.K = matrix_param("K", K, (1, 2)).copy()
        if self.p_only_default if p_only is None else p_only:
            self.K[0, 1] = 0.0
        # Feedback as accelerations [1/s^2, 1/s]: B K of eq 19, independent of the mass.
        self._kz = float(self.K[0, 0]) * self.T_v / self.design_mass
        self._kzd = float(self.K[0, 1]) * self.T_v / self.design_mass
        self._ones = np.ones(self.n_thrusters)

    def vertical_acceleration(self, h: float, hd: float, demand: Demand) -> float:
        """Commanded thrust acceleration [m/s^2]: gravity (eq 14) plus the feedback of eq 18."""
        r = h + _R
        return GM_MARS / (r * r) - self._kz * (h - demand.altitude) - self._kzd * hd

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        h, hd = altitude_and_climb_rate(state)
        m = self.vehicle.mass(state.fuel)
        return (m / self.T_v * self.vertical_acceleration(h, hd, demand)) * self._ones

    def compiled_form(self) -> object | None:
        """This law as a :class:`~.compiled.CompiledLaw` (None if a subclass changed the law)."""
        from .compiled import AltitudeLaw, AttitudeLaw, CompiledLaw, keeps_law

        if not keeps_law(self, AltitudeController, "command", "vertical_acceleration", "update"):
            return None
        return CompiledLaw(AltitudeLaw.STATE_FEEDBACK, AttitudeLaw.NONE, self.n_thrusters, self.vehicle.dry_mass,
                           T_v=self.T_v, k_altitude=np.array([self._kz, self._kzd, 0.0]))


class AltitudePController(AltitudeController):
    """P-only variant (``k2 = 0``) of :class:`AltitudeController`: poles at ``+-j sqrt(T_v k1 / m)`` (eq 21)."""

    name: ClassVar[str] = "altitude-p"
    p_only_default: ClassVar[bool] = True


class IntegralAltitudeController(Controller):
    """Altitude feedback with integral action: state ``[int (h - h_e) dt, h - h_e, h']``.

    Augmented model ``A = [[0,1,0],[0,0,1],[0,0,0]]``, ``B = [0, 0, T_v/m]``; a constant
    disturbance force (steady vertical wind drag) is cancelled by the integral term, so the
    steady altitude error is zero (the plain law leaves ``F / (T_v k1)``). The integrator
    pauses while the throttle is saturated in the direction that would wind it up further.
    """

    name: ClassVar[str] = "altitude-integral"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        poles: object = (-0.8, -1.0, -1.2),
        K: object | None = None,
        design_fuel: float | None = None,
    ) -> None:
        super().__init__(vehicle)
        self.T_v = _check_can_hover(vehicle)
        fuel = vehicle.fuel_capacity if design_fuel is None else positive_param("design_fuel", design_fuel)
        self.design_mass = vehicle.mass(fuel)
        if K is None:
            from ..design.gains import place_poles

            A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
            B = np.array([[0.0], [0.0], [self.T_v / self.design_mass]])
            K = place_poles(A, B, poles_param("poles", poles, 3)).K
        self.K = matrix_param("K", K, (1, 3)).copy()
        self._k = self.K[0] * self.T_v / self.design_mass
        self._ones = np.ones(self.n_thrusters)
        self.reset()

    def reset(self) -> None:
        self.integral = 0.0
        self._t_last: float | None = None

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        h, hd = altitude_and_climb_rate(state)
        err = h - demand.altitude
        r = h + _R
        m = self.vehicle.mass(state.fuel)
        ki, kz, kzd = self._k
        throttle = m / self.T_v * (GM_MARS / (r * r) - ki * self.integral - kz * err - kzd * hd)
        if self._t_last is not None:
            dt = t - self._t_last
            # Conditional integration (anti-windup): skip when saturated and the error pushes further.
            if dt > 0.0 and not ((throttle >= 1.0 and err < 0.0) or (throttle <= 0.0 and err > 0.0)):
                self.integral += err * dt
        self._t_last = t
        return throttle * self._ones

    def compiled_form(self) -> object | None:
        """This law as a :class:`~.compiled.CompiledLaw` (None if a subclass changed the law)."""
        from .compiled import AltitudeLaw, AttitudeLaw, CompiledLaw, keeps_law

        if not keeps_law(self, IntegralAltitudeController, "command", "update", "reset"):
            return None
        return CompiledLaw(AltitudeLaw.INTEGRAL, AttitudeLaw.NONE, self.n_thrusters, self.vehicle.dry_mass,
                           T_v=self.T_v, k_altitude=np.array(self._k, dtype=float))



