"""Attitude laws: Euler-angle state feedback (eq 23-28) and a quaternion law without gimbal lock.

Both are ``u = -s K e`` with ``e`` the attitude/rate error and ``s = m / m_d`` for a vehicle
whose inertia scales with its mass (``B`` of eq 25-26 goes as ``1/m``, so ``B K`` and the
closed-loop poles stay as designed while fuel burns); ``s = 1`` for a fixed inertia.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar, TypedDict, Unpack

import numpy as np

from lander_sim.physics.rotation import components, euler_to_quat, quat_conj, quat_mult_components
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ._params import matrix_param, poles_param, positive_param
from .base import UPRIGHT_EULER, Controller, ControllerError, Demand, wrap_angle
from .params import DESIGN_FUEL, Param, ParamTable, any_value, matrix, poles

if TYPE_CHECKING:
    from ..design.gains import GainDesign


class QuaternionAttitudeParams(TypedDict, total=False):
    """Keyword parameters of :class:`QuaternionAttitudeController` (its table: :data:`QUATERNION_ROWS`)."""

    poles: object
    K: object | None
    design_fuel: float | None


class EulerAttitudeParams(QuaternionAttitudeParams, total=False):
    """Keyword parameters of :class:`EulerAttitudeController`: the quaternion law's plus ``design_attitude``."""

    design_attitude: object


#: Both attitude laws' parameters (eq 28; the quaternion law's model is eq 28 with ``J = I``).
QUATERNION_ROWS: tuple[Param, ...] = (
    Param("poles", (-1.0,) * 6, "1/s", "6 poles, Re < 0",
          "closed-loop poles of the attitude and body rate errors, placed at the design fuel", poles(6)),
    Param("K", None, "1/rad, s/rad", "none or N x 6", "given gain (N thrusters), used verbatim instead of placing the poles",
          any_value),  # its shape is the vehicle's: the law checks it
    DESIGN_FUEL,
)

#: The Euler law's parameters: both laws' plus the attitude its model is linearised at.
EULER_ROWS: tuple[Param, ...] = QUATERNION_ROWS + (
    Param("design_attitude", UPRIGHT_EULER, "rad", "3 angles, sin theta != 0",
          "ZXZ Euler angles (phi, theta, psi) the model is linearised at", matrix((3,))),
)


class _AttitudeLaw(Controller):
    """Shared construction: gains from a model's ``(A, B)`` by pole placement or given ``K``."""

    AXES: ClassVar[tuple[str, ...]] = ("attitude",)

    def __init__(self, vehicle: Vehicle, *, K: object | None, design_fuel: float | None) -> None:
        super().__init__(vehicle)
        if vehicle.n_thrusters == 0:
            raise ControllerError("vehicle has no thrusters: an attitude law cannot work")
        fuel = vehicle.fuel_capacity if design_fuel is None else positive_param("design_fuel", design_fuel)
        self.design_fuel = fuel
        self.design_mass = vehicle.mass(fuel)
        self._mass_scaled = vehicle.gyration_sq is not None
        self._K_given = K
        self.design_method = "given"

    def _finish(self, design: GainDesign | None) -> None:
        K = design.K if design is not None else self._K_given
        if design is not None:
            self.design_method = design.method
        self.K = matrix_param("K", K, (self.n_thrusters, 6))
        self._e = np.zeros(6)  # reused error buffer: no per-step allocation

    def _scale(self, state: StateView) -> float:
        return self.vehicle.mass(state.fuel) / self.design_mass if self._mass_scaled else 1.0

    def compiled_form(self) -> object | None:
        """This law as a :class:`~.compiled.CompiledLaw` (None if a subclass changed the law)."""
        from .compiled import AltitudeLaw, AttitudeLaw, CompiledLaw, keeps_law

        kinds = {EulerAttitudeController: AttitudeLaw.EULER, QuaternionAttitudeController: AttitudeLaw.QUATERNION}
        base = next((b for b in kinds if isinstance(self, b)), None)
        if base is None or not keeps_law(self, base, "command", "error", "update", "_scale"):
            return None
        return CompiledLaw(AltitudeLaw.NONE, kinds[base], self.n_thrusters, self.vehicle.dry_mass,
                           K_attitude=np.array(self.K, dtype=float), attitude_design_mass=self.design_mass,
                           attitude_mass_scaled=self._mass_scaled)


class EulerAttitudeController(_AttitudeLaw):
    """Euler-angle attitude feedback (eq 28): ``u = -K [E - E_d, omega - omega_d]``, ``K`` (N x 6).

    ``K[i][j]``: thruster ``i`` responds to state ``j`` of ``[phi, theta, psi, wx, wy, wz]``.
    Designed by pole placement (default all six poles at -1, the seed's choice: needs
    ``place_varga``) on the model linearised at ``design_attitude`` (default upright,
    ``(0, pi/2, 0)``). Angle errors are wrapped to [-pi, pi]. Near ``sin theta = 0`` the
    measured ``phi`` and ``psi`` are ill defined and this law misbehaves (gimbal lock).
    """

    name: ClassVar[str] = "attitude-euler"
    PARAMS: ClassVar[ParamTable] = ParamTable(EULER_ROWS)

    def __init__(self, vehicle: Vehicle, **params: Unpack[EulerAttitudeParams]) -> None:
        p = self.PARAMS.resolve(params, self.name)
        super().__init__(vehicle, K=p["K"], design_fuel=p["design_fuel"])  # type: ignore[arg-type]  # checked by its row
        design = None
        if p["K"] is None:
            from ..design.attitude import attitude_model
            from ..design.gains import place_poles

            E_d = matrix_param("design_attitude", p["design_attitude"], (3,))
            if abs(math.sin(E_d[1])) < 1e-3:
                raise ControllerError(f"design_attitude: theta = {E_d[1]} is at the Euler singularity")
            model = attitude_model(vehicle, self.design_fuel, E_d)
            design = place_poles(model.A, model.B, poles_param("poles", p["poles"], 6))
        self._finish(design)

    def error(self, state: StateView, demand: Demand) -> np.ndarray:
        """``[E - E_d (wrapped), omega_B - omega_d]`` in the reused buffer."""
        (f, th, p), (fd, thd, pd) = state.euler.tolist(), demand.attitude
        (wx, wy, wz), (wxd, wyd, wzd) = state.omega_B.tolist(), demand.omega_B
        e = self._e
        e[:] = (wrap_angle(f - fd), th - thd, wrap_angle(p - pd), wx - wxd, wy - wyd, wz - wzd)
        return e

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        return -self._scale(state) * (self.K @ self.error(state, demand))


class QuaternionAttitudeController(_AttitudeLaw):
    """Quaternion attitude feedback: ``u = -K [2 v_err, omega - omega_d]``, no gimbal lock.

    ``q_err = q_d* x q`` (body-frame error, ``q = q_d x q_err``), sign chosen so ``s >= 0``
    (shortest rotation). Near the demand, ``2 v_err`` is the body-frame rotation vector and
    ``(2 v_err)' = omega`` (eq 14), so ``K`` is designed on
    :func:`~lander_autopilot.design.attitude.quaternion_attitude_model` (eq 28 with ``J = I``)
    with the same poles and method as the Euler law. Unlike the Euler angles, ``v_err`` is
    smooth everywhere, so the law is well defined at every attitude.
    """

    name: ClassVar[str] = "attitude-quaternion"
    PARAMS: ClassVar[ParamTable] = ParamTable(QUATERNION_ROWS)

    def __init__(self, vehicle: Vehicle, **params: Unpack[QuaternionAttitudeParams]) -> None:
        p = self.PARAMS.resolve(params, self.name)
        super().__init__(vehicle, K=p["K"], design_fuel=p["design_fuel"])  # type: ignore[arg-type]  # checked by its row
        design = None
        if p["K"] is None:
            from ..design.attitude import quaternion_attitude_model
            from ..design.gains import place_poles

            model = quaternion_attitude_model(vehicle, self.design_fuel)
            design = place_poles(model.A, model.B, poles_param("poles", p["poles"], 6))
        self._finish(design)
        self._qd_key: tuple[float, float, float] | None = None
        self._qd_conj = np.zeros(4)

    def error(self, state: StateView, demand: Demand) -> np.ndarray:
        """``[2 v_err, omega_B - omega_d]`` in the reused buffer."""
        if demand.attitude != self._qd_key:  # the demand quaternion changes rarely: cache it
            self._qd_conj = quat_conj(euler_to_quat(np.asarray(demand.attitude)))
            self._qd_key = demand.attitude
        return self._error(self._qd_conj, state, demand.omega_B)

    def _error(self, qd_conj: np.ndarray | tuple[float, float, float, float], state: StateView,
               omega_d: tuple[float, float, float]) -> np.ndarray:
        qs, qx, qy, qz = quat_mult_components(components(qd_conj), components(state.q))
        k = 2.0 if qs >= 0.0 else -2.0
        (wx, wy, wz), (wxd, wyd, wzd) = state.omega_B.tolist(), omega_d
        e = self._e
        e[:] = (k * qx, k * qy, k * qz, wx - wxd, wy - wyd, wz - wzd)
        return e

    def command_toward(self, q_d: np.ndarray, state: StateView) -> np.ndarray:
        """The law's throttles (unclipped) toward the attitude ``q_d`` (world -> body), at rest: for
        laws that compute their demand as a quaternion (no Euler angles, no singularity)."""
        s, x, y, z = components(q_d)
        return -self._scale(state) * (self.K @ self._error((s, -x, -y, -z), state, (0.0, 0.0, 0.0)))  # q_d* (eq 11)

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        return -self._scale(state) * (self.K @ self.error(state, demand))
