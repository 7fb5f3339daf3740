"""Ground-speed law (seed 2, section 6: "Can you control the ground speed of the lander as well as
the orientation and altitude?"): horizontal velocity through the thrust vector, with integral action.

Two loops on the model of :mod:`lander_autopilot.design.translational` (local ENU frame):

* outer, per horizontal axis: ``a_h = -k_p e - k_i int e dt`` with ``e = v_h - v_demand``, gains by
  pole placement (or LQR) on :func:`~lander_autopilot.design.translational.horizontal_velocity_model`.
  The specific force asked of the thrust is ``f = a_h + (g + a_U) up``; its direction is the
  demand attitude (body z along ``f``, body x kept as close to east as possible), its tilt from
  the vertical limited to ``max_tilt``;
* inner: the quaternion attitude law (control reference eq 28 with ``J = I``, poles all -2) tracks
  that attitude, and the collective throttle ``m (g + a_U) / (T_v cos tilt)`` keeps the vertical
  thrust what the vertical law asks (``a_U``: the altitude law, eq 18, here; the landing law
  replaces it with its descent-rate law).

The attitude loop (poles at -2) is four times as fast as the outer loop (default poles
-0.45, -0.5), so the outer loop sees the tilt it asks for after a short lag. With the combined
law's attitude poles (-1, only twice as fast) the 50 m/s stop rings: +-2.6 m/s for a minute. Saturation is handled
as by the summed laws (:class:`~.combined.SumController`): the attitude law's differential
throttles keep priority over the collective. The integrator pauses while the tilt limit clips
``a_h`` (anti-windup), so a steady wind's drag is cancelled with no steady ground-speed error and
a 50 m/s start does not wind it up.
"""
from __future__ import annotations

import math
from typing import ClassVar, Protocol, TypedDict, Unpack

import numpy as np

from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.rotation import cross3, matrix_to_quat, quat_to_euler, quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..design.translational import local_frame
from ._params import matrix_param, poles_param
from .altitude import AltitudeController
from .attitude import QuaternionAttitudeController
from .base import Controller, Demand
from .combined import CombinedQuaternionController, Mix, SumController
from .params import DESIGN_FUEL, Param, ParamTable, below, lqr_weights, optional, poles


class _Collective(Controller):
    """The summed law's "altitude" part: the collective throttle the owner computed this step."""

    name: ClassVar[str] = "collective"

    def __init__(self, vehicle: Vehicle) -> None:
        super().__init__(vehicle)
        self.level = 0.0
        self._ones = np.ones(self.n_thrusters)

    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        return self.level * self._ones


class VerticalLaw(Protocol):
    """A part flying the ground-speed law's vertical loop in eq 18's place (:attr:`GroundSpeedController.vertical_law`)."""

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        """Thrust acceleration wanted along up [m/s^2] (gravity included) at altitude ``h`` [m], climb rate ``hd`` [m/s]."""
        ...


class GroundSpeedParams(TypedDict, total=False):
    """Keyword parameters of :class:`GroundSpeedController` (its table: :attr:`GroundSpeedController.PARAMS`)."""

    velocity_poles: object
    velocity_lqr: object | None
    max_tilt: float
    altitude_poles: object
    attitude_poles: object
    design_fuel: float | None


_SUM = CombinedQuaternionController.PARAMS  # the altitude and attitude parts' rows, as a summed law names them


class GroundSpeedController(SumController):
    """Holds the demand altitude and tracks the demand horizontal velocity (zero if none).

    Parameters: the table :attr:`PARAMS` (``lander controllers ground-speed``): the outer loop's
    ``velocity_poles`` (per axis) or ``velocity_lqr`` (``[q_int, q_e, r]``: LQR instead of
    placement), ``max_tilt``, and the parts' ``altitude_poles``, ``attitude_poles`` and ``design_fuel``.
    """

    name: ClassVar[str] = "ground-speed"
    PARAMS: ClassVar[ParamTable] = ParamTable((
        Param("velocity_poles", (-0.45, -0.5), "1/s", "2 poles, Re < 0", "the ground-speed loop's poles (per axis)",
              poles(2)),
        Param("velocity_lqr", None, "1/m^2, s^2/m^2, s^4/m^2", "none or [q_int >= 0, q_e >= 0, r > 0]",
              "the ground-speed loop's LQR weights, used instead of velocity_poles", optional(lqr_weights)),
        Param("max_tilt", 0.7, "rad", "(0, 1.3)", "tilt limit of the thrust from the vertical",
              below(1.3, "1.3 rad (75 deg)")),
        _SUM["altitude_poles"],
        _SUM["attitude_poles"].with_default((-2.0,) * 6),  # four times the outer loop's speed (module docstring)
        DESIGN_FUEL,
    ))

    def __init__(self, vehicle: Vehicle, **params: Unpack[GroundSpeedParams]) -> None:
        from ..design.gains import lqr, place_poles
        from ..design.translational import horizontal_velocity_model

        p = GroundSpeedController.PARAMS.resolve(params, GroundSpeedController.name)
        self.max_tilt = float(p["max_tilt"])  # type: ignore[arg-type]  # checked by its row
        A, B = horizontal_velocity_model()
        if p["velocity_lqr"] is None:
            self.velocity_design = place_poles(A, B, poles_param("velocity_poles", p["velocity_poles"], 2))
        else:
            qi, qe, r = matrix_param("velocity_lqr", p["velocity_lqr"], (3,))
            self.velocity_design = lqr(A, B, np.diag([qi, qe]), np.array([[r]]))
        self.k_i, self.k_p = (float(k) for k in self.velocity_design.K[0])
        design_fuel = p["design_fuel"]
        self.vertical = AltitudeController(vehicle, poles=p["altitude_poles"], design_fuel=design_fuel)  # type: ignore[arg-type]
        self.T_v = self.vertical.T_v
        attitude = QuaternionAttitudeController(vehicle, poles=p["attitude_poles"], design_fuel=design_fuel)  # type: ignore[arg-type]
        super().__init__(vehicle, _Collective(vehicle), attitude)
        self._integral = np.zeros(2)
        self.reset()

    def reset(self) -> None:
        super().reset()
        self._integral = np.zeros(2)
        self._t_last: float | None = None
        #: Last step's figures (diagnostics and tests): ENU velocity [m/s], tilt demand [rad].
        self.v_local = np.zeros(3)
        self.tilt_demand = 0.0
        self.tilt_clipped = False
        self.lift_force = 0.0
        self.thrust_axis_W = np.zeros(3)
        #: World vector the demand body x is kept nearest to; None: east (:meth:`heading_axis`).
        self.heading_W: np.ndarray | None = None

    @property
    def velocity_integral(self) -> np.ndarray:
        """The outer loop's integral of the velocity error, ENU ``(east, north)`` [m] (a copy)."""
        return self._integral.copy()

    def preset_velocity_integral(self, value: np.ndarray) -> None:
        """Set the outer loop's integral, ENU ``(east, north)`` [m] (a law taking over a flight in a wind)."""
        self._integral[:] = value

    def clear_velocity_integral(self) -> None:
        """Set the outer loop's integral to zero (a law that flies the horizontal loop itself for a while)."""
        self._integral[:] = 0.0

    # --- the parts a subclass (the landing law) changes ---------------------------------------

    #: A part flying the vertical loop in eq 18's place (the de-orbit's hover capture); None: eq 18.
    vertical_law: VerticalLaw | None = None

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        """Thrust acceleration wanted along ``up`` [m/s^2] (gravity included): eq 18 about the demand,
        or the :attr:`vertical_law`'s."""
        if self.vertical_law is not None:
            return self.vertical_law.vertical_acceleration(t, h, hd, demand)
        return self.vertical.vertical_acceleration(h, hd, demand)

    def tilt_limit(self, h: float) -> float:
        """Largest tilt of the thrust from the vertical the outer loop may ask for [rad]."""
        return self.max_tilt

    def horizontal_limit(self, h: float, lift: float) -> float:
        """Largest horizontal thrust acceleration [m/s^2] the outer loop may ask for, at ``lift``
        [m/s^2] along up: the tilt limit's, ``lift tan(tilt_limit(h))``."""
        return lift * math.tan(self.tilt_limit(h))

    def holds_ground_speed(self) -> bool:
        """False while the law lets the horizontal motion be (the landing law's coast: there is no
        thrust to tilt, and chasing the wind with attitude alone only burns fuel)."""
        return True

    def horizontal_acceleration(self, state: StateView, L: np.ndarray, h: float, v_L: np.ndarray,
                                error: np.ndarray) -> np.ndarray:
        """Horizontal thrust acceleration asked for, ENU ``(east, north)`` [m/s^2], before the tilt
        limit: the PI law on the velocity error ``error`` (``L``: the local frame's axes in world
        coordinates, rows; ``h`` the altitude [m]; ``v_L`` the ENU velocity [m/s])."""
        return -self.k_p * error - self.k_i * self._integral

    def axis_bias(self, t: float, state: StateView, L: np.ndarray, wanted: np.ndarray) -> np.ndarray | None:
        """A correction to the thrust axis asked of the attitude law, ENU ``(east, north)`` as the axis's
        horizontal over vertical component, given the one ``wanted`` (the same form); None: none (here)."""
        return None

    def velocity_demand(self, demand: Demand) -> tuple[float, float]:
        """Horizontal velocity to track, ENU ``(east, north)`` [m/s]."""
        return demand.velocity if demand.velocity is not None else (0.0, 0.0)

    # --- the law ---------------------------------------------------------------------------

    def mixed_command(self, t: float, state: StateView, demand: Demand) -> Mix:
        r_W = state.r_W
        L = local_frame(r_W)
        r = float(np.linalg.norm(r_W))
        h = r - MARS_RADIUS
        v = L @ state.v_W
        self.v_local = v
        hd = float(v[2])
        a_up = self.vertical_acceleration(t, h, hd, demand)
        ve, vn = self.velocity_demand(demand)
        e = np.array([v[0] - ve, v[1] - vn])
        hold = self.holds_ground_speed()
        a_h = self.horizontal_acceleration(state, L, h, v, e) if hold else np.zeros(2)
        # Tilt limit: |a_h| <= (g + a_U) tan(max tilt). a_up may be ~0 (coasting): keep a floor so
        # the demand direction stays defined.
        lift = max(a_up, 0.2 * GM_MARS / (r * r))
        lim = self.horizontal_limit(h, lift)
        n_h = math.hypot(float(a_h[0]), float(a_h[1]))
        clipped = n_h > lim
        if clipped:
            a_h *= lim / n_h
        if self._t_last is not None and hold and not clipped:
            dt = t - self._t_last
            if dt > 0.0:
                self._integral += e * dt
        self._t_last = t
        self.tilt_clipped = clipped
        bias = self.axis_bias(t, state, L, a_h / lift)
        if bias is not None:
            a_h = a_h + lift * bias
        # Demand attitude: body z along f = a_h + lift up; body x as near east as possible.
        f = L.T @ np.array([a_h[0], a_h[1], lift])
        b3 = f / float(np.linalg.norm(f))
        self.thrust_axis_W = b3  # wanted body z, world frame (a spinning lander steers its spin axis to it)
        x_ref = self.heading_axis(state, L)
        b1 = x_ref - float(x_ref @ b3) * b3
        b1 /= float(np.linalg.norm(b1))
        q_d = matrix_to_quat(np.array([b1, cross3(b3, b1), b3]))  # rows: body axes in world (world -> body)
        self.tilt_demand = math.acos(min(1.0, float(b3 @ L[2])))
        phi, theta, psi = (float(a) for a in quat_to_euler(q_d))
        inner = Demand(altitude=demand.altitude, attitude=(phi, theta, psi))
        # Collective: the vertical share of the thrust along the *current* body z.
        z_B_up = float(quat_to_matrix(state.q)[2] @ L[2])
        m = self.vehicle.mass(state.fuel)
        self.lift_force = m * a_up / max(z_B_up, 0.5)  # [N] along body z
        self.collective.level = self.lift_force / self.T_v
        return self.mix(t, state, inner)

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray:
        """World vector the demand body x is kept nearest to: ``heading_W`` if set, else east (a
        subclass may give the heading up)."""
        return L[0] if self.heading_W is None else self.heading_W

    def mix(self, t: float, state: StateView, inner: Demand) -> Mix:
        """Throttles from the collective and the attitude law (the summed law's mix, attitude priority)."""
        return SumController.mixed_command(self, t, state, inner)

    @property
    def collective(self) -> _Collective:
        return self.altitude  # type: ignore[return-value]  # built as a _Collective in __init__; typed as the base's part
