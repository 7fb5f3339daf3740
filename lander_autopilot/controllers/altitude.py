"""Altitude laws: the extended program's baseline, state feedback (eq 18-21) and integral action.

All use one throttle on every thruster. Altitude ``h = |r_W| - R_mars`` and climb rate
``h' = v_W . r_hat`` come from the state; ``z = R_mars + h`` is eq 9's distance from the centre.
"""
from __future__ import annotations

from typing import ClassVar, TypedDict, Unpack

import numpy as np

from lander_sim.physics.constants import GM_MARS
from lander_sim.physics.constants import MARS_RADIUS as _R
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.altitude import vertical_thrust
from ._params import matrix_param, poles_param, positive_param
from .base import Controller, ControllerError, Demand, altitude_and_climb_rate
from .params import DESIGN_FUEL, Param, ParamTable, boolean, finite, matrix, optional, poles


def _check_can_hover(vehicle: Vehicle) -> float:
    tv = vertical_thrust(vehicle)
    if tv <= 0.0:
        raise ControllerError(f"vehicle has no upward thrust (T_v = {tv} N): an altitude law cannot work")
    return tv


class BaselineParams(TypedDict, total=False):
    """Keyword parameters of :class:`BaselineController` (its table: :attr:`BaselineController.PARAMS`)."""

    kp: float
    kd: float


class AltitudeParams(TypedDict, total=False):
    """Keyword parameters of :class:`AltitudeController` (its table: :data:`ALTITUDE_ROWS`)."""

    poles: object
    K: object | None
    design_fuel: float | None
    p_only: bool | None


class IntegralAltitudeParams(TypedDict, total=False):
    """Keyword parameters of :class:`IntegralAltitudeController` (its table: its ``PARAMS``)."""

    poles: object
    K: object | None
    design_fuel: float | None


#: The altitude law's parameters (eq 18-19); ``altitude-p`` is the same law with ``p_only`` true.
ALTITUDE_ROWS: tuple[Param, ...] = (
    Param("poles", (-0.9, -1.1), "1/s", "2 poles, Re < 0", "closed-loop poles of [h - h_e, h'] (eq 19), placed at the design fuel",
          poles(2)),
    Param("K", None, "1/m, s/m", "none or 1 x 2", "given gain, used verbatim instead of placing the poles",
          optional(matrix((1, 2)))),
    DESIGN_FUEL,
    Param("p_only", False, "-", "true, false", "k2 = 0: no climb-rate feedback, the marginal P-only law of eq 21",
          optional(boolean)),
)


class BaselineController(Controller):
    """The extended program's own autopilot: ``t = t_e + k_p (z_e - z) + k_d (0 - z')`` on all thrusters.

    ``t_e = G M m / (|r|^2 sum T_max)`` at the current mass and radius; ``k_p = 0.1``, ``k_d = 0``
    by default (P-only: marginally stable, eq 21, so it oscillates; seed 2 task 1).
    """

    name: ClassVar[str] = "baseline"
    AXES: ClassVar[tuple[str, ...]] = ("altitude",)
    PARAMS: ClassVar[ParamTable] = ParamTable((
        Param("kp", 0.1, "1/m", "finite", "throttle per metre of altitude error", finite),
        Param("kd", 0.0, "s/m", "finite", "throttle per m/s of climb rate (0: P-only, eq 21)", finite),
    ))

    def __init__(self, vehicle: Vehicle, **params: Unpack[BaselineParams]) -> None:
        super().__init__(vehicle)
        p = self.PARAMS.resolve(params, self.name)
        self.kp = float(p["kp"])  # type: ignore[arg-type]  # each checked by its row: a float
        self.kd = float(p["kd"])  # type: ignore[arg-type]
        self._tmax = sum(t.max_thrust for t in vehicle.thrusters if t.enabled)
        if self._tmax <= 0.0:
            raise ControllerError("vehicle has no enabled thruster: the baseline autopilot cannot work")
        self._ones = np.ones(self.n_thrusters)

    def gains(self) -> dict[str, np.ndarray]:
        """``kp`` [1/m] and ``kd`` [s/m], the law's two gains."""
        return {"kp": np.array(self.kp), "kd": np.array(self.kd)}

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
    AXES: ClassVar[tuple[str, ...]] = ("altitude",)
    PARAMS: ClassVar[ParamTable] = ParamTable(ALTITUDE_ROWS)

    def __init__(self, vehicle: Vehicle, **params: Unpack[AltitudeParams]) -> None:
        super().__init__(vehicle)
        p = self.PARAMS.resolve(params, self.name)
        self.T_v = _check_can_hover(vehicle)
        design_fuel, K = p["design_fuel"], p["K"]
        fuel = vehicle.fuel_capacity if design_fuel is None else positive_param("design_fuel", design_fuel)
        self.design_mass = vehicle.mass(fuel)
        if K is None:
            from ..design.altitude import altitude_model
            from ..design.gains import place_poles

            model = altitude_model(vehicle, fuel, 0.0)
            K = place_poles(model.A, model.B, poles_param("poles", p["poles"], 2)).K
        self.K = matrix_param("K", K, (1, 2)).copy()
        p_only = p["p_only"]
        if self.PARAMS["p_only"].default if p_only is None else p_only:
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
    PARAMS: ClassVar[ParamTable] = ParamTable(
        row.with_default(True) if row.name == "p_only" else row for row in ALTITUDE_ROWS)


class IntegralAltitudeController(Controller):
    """Altitude feedback with integral action: state ``[int (h - h_e) dt, h - h_e, h']``.

    Augmented model ``A = [[0,1,0],[0,0,1],[0,0,0]]``, ``B = [0, 0, T_v/m]``; a constant
    disturbance force (steady vertical wind drag) is cancelled by the integral term, so the
    steady altitude error is zero (the plain law leaves ``F / (T_v k1)``). The integrator
    pauses while the throttle is saturated in the direction that would wind it up further.
    """

    name: ClassVar[str] = "altitude-integral"
    AXES: ClassVar[tuple[str, ...]] = ("altitude",)
    PARAMS: ClassVar[ParamTable] = ParamTable((
        Param("poles", (-0.8, -1.0, -1.2), "1/s", "3 poles, Re < 0",
              "closed-loop poles of [int (h - h_e) dt, h - h_e, h'], placed at the design fuel", poles(3)),
        Param("K", None, "1/(m s), 1/m, s/m", "none or 1 x 3", "given gain, used verbatim instead of placing the poles",
              optional(matrix((1, 3)))),
        DESIGN_FUEL,
    ))

    def __init__(self, vehicle: Vehicle, **params: Unpack[IntegralAltitudeParams]) -> None:
        super().__init__(vehicle)
        p = self.PARAMS.resolve(params, self.name)
        K, design_fuel = p["K"], p["design_fuel"]
        self.T_v = _check_can_hover(vehicle)
        fuel = vehicle.fuel_capacity if design_fuel is None else positive_param("design_fuel", design_fuel)
        self.design_mass = vehicle.mass(fuel)
        if K is None:
            from ..design.gains import place_poles

            A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
            B = np.array([[0.0], [0.0], [self.T_v / self.design_mass]])
            K = place_poles(A, B, poles_param("poles", p["poles"], 3)).K
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



