"""Summed laws (seed 2, section 4.2 task 3): altitude throttle on every thruster plus the attitude
law's differential throttles, clipped once to [0, 1]; and the LQR variant.
"""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ._params import matrix_param
from .altitude import AltitudeController, IntegralAltitudeController
from .attitude import EulerAttitudeController, QuaternionAttitudeController
from .base import UPRIGHT_EULER, Controller, ControlOutput, Demand, saturate


def mix_with_attitude_priority(collective: float, differential: np.ndarray) -> np.ndarray:
    """``collective + differential`` kept inside [0, 1] by moving the collective, not the differential.

    The differential (the attitude law's torque) is kept whole if its spread fits in [0, 1], else
    shrunk to fit; then the collective moves as little as possible into range.
    """
    d = differential
    lo, hi = float(d.min()), float(d.max())
    if hi - lo > 1.0:
        d = d * (1.0 / (hi - lo))
        lo, hi = lo / (hi - lo), hi / (hi - lo)
    return min(max(collective, -lo), 1.0 - hi) + d


class SumController(Controller):
    """``u = u_altitude + u_attitude`` (unclipped), then clipped by :meth:`Controller.update`.

    With ``attitude_priority`` (default) a sum that would saturate first gives up collective
    (altitude) throttle, keeping the attitude law's differential throttles: clipping the plain
    sum can leave every thruster at 1 (or 0) with no torque left, and a tilted lander that
    cannot turn back upright falls (seen flying from 170 degrees off upright).
    """

    def __init__(
        self, vehicle: Vehicle, altitude: Controller, attitude: Controller, attitude_priority: bool = True
    ) -> None:
        super().__init__(vehicle)
        self.altitude = altitude
        self.attitude = attitude
        self.attitude_priority = attitude_priority
        self._mixed_from: np.ndarray | None = None

    def reset(self) -> None:
        self.altitude.reset()
        self.attitude.reset()

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        u_alt = self.altitude.command(t, state, demand)
        u_att = self.attitude.command(t, state, demand)
        u = u_alt + u_att
        if not self.attitude_priority or (u.min() >= 0.0 and u.max() <= 1.0):
            return u
        # Collective c (mean altitude throttle) plus differential d.
        c = float(u_alt.mean())
        self._mixed_from = u
        return mix_with_attitude_priority(c, u - c)

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        """As :meth:`Controller.update`; giving up collective throttle counts as saturation and
        ``unclipped`` is then the plain sum the laws asked for."""
        self._mixed_from = None
        out = saturate(self.command(t, state, demand))
        if self._mixed_from is None:
            return out
        return ControlOutput(throttles=out.throttles, saturated=True, unclipped=self._mixed_from)

    def compiled_form(self) -> object | None:
        """The summed law as a :class:`~.compiled.CompiledLaw`: both parts must have one, and
        neither this class nor a subclass may change how they are summed."""
        from .compiled import AltitudeLaw, AttitudeLaw, CompiledLaw, compiled_form, keeps_law

        if not keeps_law(self, SumController, "command", "update", "reset"):
            return None
        alt, att = compiled_form(self.altitude), compiled_form(self.attitude)
        if (alt is None or att is None or alt.attitude is not AttitudeLaw.NONE or att.altitude is not AltitudeLaw.NONE
                or alt.dry_mass != att.dry_mass or alt.n_thrusters != att.n_thrusters):
            return None
        return CompiledLaw.combine(alt, att, self.attitude_priority)


class CombinedController(SumController):
    """Altitude state feedback (poles ``(-0.9, -1.1)``) + Euler attitude feedback (poles all -1)."""

    name: ClassVar[str] = "combined"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        altitude_poles: object = (-0.9, -1.1),
        attitude_poles: object = (-1.0,) * 6,
        K_altitude: object | None = None,
        K_attitude: object | None = None,
        design_fuel: float | None = None,
        design_attitude: object = UPRIGHT_EULER,
    ) -> None:
        super().__init__(
            vehicle,
            AltitudeController(vehicle, poles=altitude_poles, K=K_altitude, design_fuel=design_fuel),
            EulerAttitudeController(
                vehicle, poles=attitude_poles, K=K_attitude, design_fuel=design_fuel, design_attitude=design_attitude
            ),
        )


class CombinedQuaternionController(SumController):
    """Altitude state feedback + the quaternion attitude law (no gimbal lock)."""

    name: ClassVar[str] = "combined-quaternion"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        altitude_poles: object = (-0.9, -1.1),
        attitude_poles: object = (-1.0,) * 6,
        K_altitude: object | None = None,
        K_attitude: object | None = None,
        design_fuel: float | None = None,
    ) -> None:
        super().__init__(
            vehicle,
            AltitudeController(vehicle, poles=altitude_poles, K=K_altitude, design_fuel=design_fuel),
            QuaternionAttitudeController(vehicle, poles=attitude_poles, K=K_attitude, design_fuel=design_fuel),
        )


class IntegralController(SumController):
    """Altitude with integral action (rejects a constant disturbance) + Euler attitude feedback."""

    name: ClassVar[str] = "integral"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        altitude_poles: object = (-0.8, -1.0, -1.2),
        attitude_poles: object = (-1.0,) * 6,
        K_altitude: object | None = None,
        K_attitude: object | None = None,
        design_fuel: float | None = None,
        design_attitude: object = UPRIGHT_EULER,
    ) -> None:
        super().__init__(
            vehicle,
            IntegralAltitudeController(vehicle, poles=altitude_poles, K=K_altitude, design_fuel=design_fuel),
            EulerAttitudeController(
                vehicle, poles=attitude_poles, K=K_attitude, design_fuel=design_fuel, design_attitude=design_attitude
            ),
        )


#: Default LQR weights. Bryson's rule: 1 / (acceptable excursion)^2 with 1 m and 1 m/s for
#: altitude, 0.1 rad and 0.1 rad/s for attitude, and a throttle excursion of 0.1 (altitude) /
#: 0.1 per thruster (attitude): fast enough to hold a hover, gentle enough not to saturate.
LQR_Q_ALTITUDE = (1.0, 1.0)
LQR_R_ALTITUDE = 100.0
LQR_Q_ATTITUDE = (100.0, 100.0, 100.0, 100.0, 100.0, 100.0)
LQR_R_ATTITUDE = 100.0


class LQRController(SumController):
    """Combined law with both gains from LQR (``control.lqr``) instead of pole placement.

    ``Q_*`` are the diagonals of the state weights, ``R_*`` the (scalar) input weights.
    """

    name: ClassVar[str] = "lqr"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        Q_altitude: object = LQR_Q_ALTITUDE,
        R_altitude: float = LQR_R_ALTITUDE,
        Q_attitude: object = LQR_Q_ATTITUDE,
        R_attitude: float = LQR_R_ATTITUDE,
        design_fuel: float | None = None,
        design_attitude: object = UPRIGHT_EULER,
    ) -> None:
        from ..design.altitude import altitude_model
        from ..design.attitude import attitude_model
        from ..design.gains import lqr

        fuel = vehicle.fuel_capacity if design_fuel is None else design_fuel
        qa = matrix_param("Q_altitude", Q_altitude, (2,))
        ra = matrix_param("R_altitude", R_altitude, ())
        qt = matrix_param("Q_attitude", Q_attitude, (6,))
        rt = matrix_param("R_attitude", R_attitude, ())
        alt = altitude_model(vehicle, fuel, 0.0)
        att = attitude_model(vehicle, fuel, matrix_param("design_attitude", design_attitude, (3,)))
        self.altitude_design = lqr(alt.A, alt.B, np.diag(qa), ra * np.eye(1))
        self.attitude_design = lqr(att.A, att.B, np.diag(qt), rt * np.eye(vehicle.n_thrusters))
        super().__init__(
            vehicle,
            AltitudeController(vehicle, K=self.altitude_design.K, design_fuel=fuel),
            EulerAttitudeController(vehicle, K=self.attitude_design.K, design_fuel=fuel),
        )
