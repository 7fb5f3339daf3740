"""Summed laws (seed 2, section 4.2 task 3): altitude throttle on every thruster plus the attitude
law's differential throttles, clipped once to [0, 1]; and the LQR variant.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, TypedDict, Unpack, cast

import numpy as np
from numpy.typing import ArrayLike

from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ._params import matrix_param
from .altitude import AltitudeController, IntegralAltitudeController
from .attitude import EulerAttitudeController, QuaternionAttitudeController
from .base import Controller, ControlOutput, Demand, saturate, value_range
from .params import DESIGN_FUEL, Param, ParamTable, positive, weights


def mix_with_attitude_priority(collective: float, differential: np.ndarray) -> np.ndarray:
    """``collective + differential`` kept inside [0, 1] by moving the collective, not the differential.

    The differential (the attitude law's torque) is kept whole if its spread fits in [0, 1], else
    shrunk to fit; then the collective moves as little as possible into range.
    """
    d = differential
    lo, hi = value_range(d)
    if hi - lo > 1.0:
        d = d * (1.0 / (hi - lo))
        lo, hi = lo / (hi - lo), hi / (hi - lo)
    return min(max(collective, -lo), 1.0 - hi) + d


@dataclass
class CollectiveHeadroom:
    """The share of the collective throttle the attitude law takes when the mixer's ceiling binds.

    Under attitude priority (:func:`mix_with_attitude_priority`) the collective is capped at
    ``1 - max(d)``, ``d`` the attitude law's differential. Under the canopy in a wind that torque is
    steady (the canopy pulls off the body axis): in the 200 km sweep's worst flights one thruster
    sat at full throttle through the braking with the mean at 0.89-0.95, so a braking planned on the
    full collective ran 1-5 m under the hover. ``share`` is ``max(d)`` filtered with time constant
    ``time_constant`` [s], updated only in the periods its caller marks ``pinned`` and held between
    them. The descent law (:class:`.deorbit.DescentToAltitude`) marks every period in which the mixer
    gave way, at the floor as well as at the ceiling: as the braking begins, the collective still
    low and the thrust axis turning, that is one period in a typical flight, which alone teaches a
    share of ~0.03; marked at the ceiling only, the 200 km sweep's 20 worst flights lost most of
    the gain (median 1.148 x against 1.060, docs/deorbit.md). The MPC marks the ceiling only.
    """

    time_constant: float = 1.0
    share: float = 0.0

    def update(self, differential_top: float, pinned: bool, dt: float) -> None:
        """``differential_top``: ``max(d)`` this period; ``pinned``: learn from this period; ``dt`` [s]."""
        if pinned:
            self.share += min(dt / self.time_constant, 1.0) * (max(differential_top, 0.0) - self.share)

    @property
    def available(self) -> float:
        """Fraction of the full collective the braking can count on."""
        return 1.0 - self.share


@dataclass(frozen=True)
class Mix:
    """A summed law's throttles before clipping, and whether its mixer gave way.

    Attributes
    ----------
    throttles : ndarray (N,)
        What the law asks of the thrusters; :meth:`output` clips them once.
    mixed_from : ndarray (N,) or None
        ``None`` if ``throttles`` are what the parts asked for. Otherwise the mixer changed them to
        fit [0, 1] (the collective gave way, or an allocation saturated): that counts as
        saturation, and ``mixed_from`` (what was asked) is reported as ``ControlOutput.unclipped``.
    """

    throttles: np.ndarray
    mixed_from: np.ndarray | None = None

    def output(self) -> ControlOutput:
        """The step's result: ``throttles`` clipped to [0, 1], saturated if clipped or mixed."""
        out = saturate(self.throttles)
        if self.mixed_from is None:
            return out
        return ControlOutput(throttles=out.throttles, saturated=True, unclipped=self.mixed_from)


class SumController(Controller):
    """``u = u_altitude + u_attitude`` (unclipped), then clipped once by :meth:`update`.

    With ``attitude_priority`` (default) a sum that would saturate first gives up collective
    (altitude) throttle, keeping the attitude law's differential throttles: clipping the plain
    sum can leave every thruster at 1 (or 0) with no torque left, and a tilted lander that
    cannot turn back upright falls (seen flying from 170 degrees off upright).
    :meth:`mixed_command` is the law; a subclass that changes it overrides that method.
    """

    def __init__(
        self, vehicle: Vehicle, altitude: Controller, attitude: Controller, attitude_priority: bool = True
    ) -> None:
        super().__init__(vehicle)
        self.altitude = altitude
        self.attitude = attitude
        self.attitude_priority = attitude_priority

    #: Both parts': the altitude (eq 16) and the attitude (eq 28) model.
    AXES: ClassVar[tuple[str, ...]] = ("altitude", "attitude")

    def gains(self) -> dict[str, np.ndarray]:
        """Each part's gains under the name the summed law takes them by (``K_altitude``,
        ``K_attitude``; another part's gain keeps its own name with the part's suffix)."""
        out: dict[str, np.ndarray] = {}
        for part, suffix in ((self.altitude, "altitude"), (self.attitude, "attitude")):
            out.update({f"{k}_{suffix}": v for k, v in part.gains().items()})
        return out

    def reset(self) -> None:
        self.altitude.reset()
        self.attitude.reset()

    def mixed_command(self, t: float, state: StateView, demand: Demand) -> Mix:
        """The summed throttles before clipping, with the mixer's flag (:class:`Mix`)."""
        u_alt = self.altitude.command(t, state, demand)
        u_att = self.attitude.command(t, state, demand)
        u = u_alt + u_att
        if not self.attitude_priority or (u.min() >= 0.0 and u.max() <= 1.0):
            return Mix(u)
        # Collective c (mean altitude throttle) plus differential d.
        c = float(u_alt.mean())
        return Mix(mix_with_attitude_priority(c, u - c), mixed_from=u)

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        """:meth:`mixed_command`'s throttles (the array :meth:`Controller.command` promises)."""
        return self.mixed_command(t, state, demand).throttles

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        """As :meth:`Controller.update`; giving up collective throttle counts as saturation and
        ``unclipped`` is then the plain sum the laws asked for (:meth:`Mix.output`)."""
        return self.mixed_command(t, state, demand).output()

    def compiled_form(self) -> object | None:
        """The summed law as a :class:`~.compiled.CompiledLaw`: both parts must have one, and
        neither this class nor a subclass may change how they are summed."""
        from .compiled import AltitudeLaw, AttitudeLaw, CompiledLaw, compiled_form, keeps_law

        if not keeps_law(self, SumController, "mixed_command", "command", "update", "reset"):
            return None
        alt, att = compiled_form(self.altitude), compiled_form(self.attitude)
        if (alt is None or att is None or alt.attitude is not AttitudeLaw.NONE or att.altitude is not AltitudeLaw.NONE
                or alt.dry_mass != att.dry_mass or alt.n_thrusters != att.n_thrusters):
            return None
        return CompiledLaw.combine(alt, att, self.attitude_priority)


class SumParams(TypedDict, total=False):
    """Keyword parameters of the summed law ``combined-quaternion`` and, with
    :class:`EulerSumParams`, ``combined`` and ``integral`` (their YAML names; the tables: each
    law's ``PARAMS``, composed of its parts' rows).

    Each goes to one part, or both (``design_fuel``); one left out takes that part's default.

    * ``altitude_poles``: the altitude law's ``poles`` (default ``(-0.9, -1.1)``; with integral
      action ``(-0.8, -1.0, -1.2)``);
    * ``attitude_poles``: the attitude law's ``poles`` (default all six at -1);
    * ``K_altitude``, ``K_attitude``: given gains, used verbatim instead of a design;
    * ``design_fuel``: fuel [kg] both parts are designed at (default a full tank).
    """

    altitude_poles: ArrayLike
    attitude_poles: ArrayLike
    K_altitude: ArrayLike | None
    K_attitude: ArrayLike | None
    design_fuel: float | None


class EulerSumParams(SumParams, total=False):
    """:class:`SumParams` plus ``design_attitude``: the ZXZ Euler angles [rad] the Euler attitude
    law is linearised at (default upright, :data:`~.base.UPRIGHT_EULER`)."""

    design_attitude: ArrayLike


#: Summed-law parameter -> the altitude part's parameter, and the attitude part's.
_ALTITUDE_PART = {"altitude_poles": "poles", "K_altitude": "K", "design_fuel": "design_fuel"}
_ATTITUDE_PART = {"attitude_poles": "poles", "K_attitude": "K", "design_fuel": "design_fuel",
                  "design_attitude": "design_attitude"}


def sum_rows(altitude: type[AltitudeController | IntegralAltitudeController],
             attitude: type[EulerAttitudeController | QuaternionAttitudeController]) -> tuple[Param, ...]:
    """A summed law's rows from its parts' tables (each part's ``PARAMS``): each part's parameter
    under the summed law's name (``poles`` as ``altitude_poles`` ...) with the part's default,
    unit, range and check; ``design_fuel`` and ``design_attitude`` are the parts' own rows."""
    alt, att = altitude.PARAMS, attitude.PARAMS
    rows = [
        alt["poles"].renamed("altitude_poles", f"the altitude part's closed-loop poles ({altitude.name}'s poles)"),
        att["poles"].renamed("attitude_poles", f"the attitude part's closed-loop poles ({attitude.name}'s poles)"),
        alt["K"].renamed("K_altitude", f"the altitude part's given gain ({altitude.name}'s K)"),
        att["K"].renamed("K_attitude", f"the attitude part's given gain ({attitude.name}'s K)"),
        alt["design_fuel"],
    ]
    if "design_attitude" in att:
        rows.append(att["design_attitude"])
    return tuple(rows)


def _parts(params: Mapping[str, object], table: ParamTable, law: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The altitude part's and the attitude part's keyword arguments from a summed law's ``params``,
    every one resolved by the law's ``table`` (an unknown name or a bad value: ControllerError
    naming it) and renamed to the part's name."""
    p = table.resolve(params, law)
    alt = {_ALTITUDE_PART[k]: v for k, v in p.items() if k in _ALTITUDE_PART}
    att = {_ATTITUDE_PART[k]: v for k, v in p.items() if k in _ATTITUDE_PART}
    return alt, att


class CombinedController(SumController):
    """Altitude state feedback (poles ``(-0.9, -1.1)``) + Euler attitude feedback (poles all -1).
    Parameters: :class:`EulerSumParams`, the table :attr:`PARAMS`."""

    name: ClassVar[str] = "combined"
    PARAMS: ClassVar[ParamTable] = ParamTable(sum_rows(AltitudeController, EulerAttitudeController))

    def __init__(self, vehicle: Vehicle, **params: Unpack[EulerSumParams]) -> None:
        alt, att = _parts(params, self.PARAMS, self.name)
        super().__init__(vehicle, AltitudeController(vehicle, **alt), EulerAttitudeController(vehicle, **att))


class CombinedQuaternionController(SumController):
    """Altitude state feedback + the quaternion attitude law (no gimbal lock). Parameters:
    :class:`SumParams`, the table :attr:`PARAMS`."""

    name: ClassVar[str] = "combined-quaternion"
    PARAMS: ClassVar[ParamTable] = ParamTable(sum_rows(AltitudeController, QuaternionAttitudeController))

    def __init__(self, vehicle: Vehicle, **params: Unpack[SumParams]) -> None:
        alt, att = _parts(params, self.PARAMS, self.name)
        super().__init__(vehicle, AltitudeController(vehicle, **alt), QuaternionAttitudeController(vehicle, **att))


class IntegralController(SumController):
    """Altitude with integral action (rejects a constant disturbance) + Euler attitude feedback.
    Parameters: :class:`EulerSumParams` (``altitude_poles``: three, default ``(-0.8, -1.0, -1.2)``),
    the table :attr:`PARAMS`."""

    name: ClassVar[str] = "integral"
    PARAMS: ClassVar[ParamTable] = ParamTable(sum_rows(IntegralAltitudeController, EulerAttitudeController))

    def __init__(self, vehicle: Vehicle, **params: Unpack[EulerSumParams]) -> None:
        alt, att = _parts(params, self.PARAMS, self.name)
        super().__init__(vehicle, IntegralAltitudeController(vehicle, **alt), EulerAttitudeController(vehicle, **att))


#: Default LQR weights. Bryson's rule: 1 / (acceptable excursion)^2 with 1 m and 1 m/s for
#: altitude, 0.1 rad and 0.1 rad/s for attitude, and a throttle excursion of 0.1 (altitude) /
#: 0.1 per thruster (attitude): fast enough to hold a hover, gentle enough not to saturate.
LQR_Q_ALTITUDE = (1.0, 1.0)
LQR_R_ALTITUDE = 100.0
LQR_Q_ATTITUDE = (100.0, 100.0, 100.0, 100.0, 100.0, 100.0)
LQR_R_ATTITUDE = 100.0


class LQRParams(TypedDict, total=False):
    """Keyword parameters of :class:`LQRController` (its table: :attr:`LQRController.PARAMS`)."""

    Q_altitude: ArrayLike
    R_altitude: float
    Q_attitude: ArrayLike
    R_attitude: float
    design_fuel: float | None
    design_attitude: ArrayLike


class LQRController(SumController):
    """Combined law with both gains from LQR (``control.lqr``) instead of pole placement.

    ``Q_*`` are the diagonals of the state weights, ``R_*`` the (scalar) input weights.
    """

    name: ClassVar[str] = "lqr"
    PARAMS: ClassVar[ParamTable] = ParamTable((
        Param("Q_altitude", LQR_Q_ALTITUDE, "1/m^2, s^2/m^2", "2 numbers >= 0",
              "diagonal of the altitude state weight, on [h - h_e, h']", weights(2)),
        Param("R_altitude", LQR_R_ALTITUDE, "-", "> 0", "weight of the collective throttle", positive),
        Param("Q_attitude", LQR_Q_ATTITUDE, "1/rad^2, s^2/rad^2", "6 numbers >= 0",
              "diagonal of the attitude state weight, on the Euler angle and body rate errors", weights(6)),
        Param("R_attitude", LQR_R_ATTITUDE, "-", "> 0", "weight of each thruster's differential throttle", positive),
        DESIGN_FUEL,
        EulerAttitudeController.PARAMS["design_attitude"],
    ))

    def __init__(self, vehicle: Vehicle, **params: Unpack[LQRParams]) -> None:
        from ..design.altitude import altitude_model
        from ..design.attitude import attitude_model
        from ..design.gains import lqr

        p = self.PARAMS.resolve(params, self.name)
        design_fuel = p["design_fuel"]
        fuel = vehicle.fuel_capacity if design_fuel is None else cast(float, design_fuel)  # checked by its row
        qa = matrix_param("Q_altitude", p["Q_altitude"], (2,))
        ra = matrix_param("R_altitude", p["R_altitude"], ())
        qt = matrix_param("Q_attitude", p["Q_attitude"], (6,))
        rt = matrix_param("R_attitude", p["R_attitude"], ())
        alt = altitude_model(vehicle, fuel, 0.0)
        att = attitude_model(vehicle, fuel, matrix_param("design_attitude", p["design_attitude"], (3,)))
        self.altitude_design = lqr(alt.A, alt.B, np.diag(qa), ra * np.eye(1))
        self.attitude_design = lqr(att.A, att.B, np.diag(qt), rt * np.eye(vehicle.n_thrusters))
        super().__init__(
            vehicle,
            AltitudeController(vehicle, K=self.altitude_design.K, design_fuel=fuel),
            EulerAttitudeController(vehicle, K=self.attitude_design.K, design_fuel=fuel),
        )
