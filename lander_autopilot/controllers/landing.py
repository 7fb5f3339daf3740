"""Landing law: from a hover or a descent to touchdown under the limits, ground speed held at zero.

Horizontal motion and attitude are the ground-speed law's (:mod:`.ground_speed`, demand velocity
zero); the vertical law tracks a descent-rate profile of the height above contact
``h_c = h - L/2`` (the simulator touches down at ``h = L/2``)::

    v_d(h_c) = -sqrt(v_x^2 + 2 a_b (h_c - h_x))   above h_x   (braking limb)
    v_d(h_c) = -(v_td + k_f h_c)                   below h_x   (flare limb)
    a_U      = g + k_v (v_d - h') + dv_d/dt

The braking limb decelerates at a constant ``a_b = brake_fraction (T_v / m - g)`` (a fraction of
the net thrust acceleration, so thrust and mass errors leave a margin); the flare limb is
exponential, its descent rate falling to ``v_td`` at contact. It starts at ``v_x = a_b / k_f``,
``h_x = (v_x - v_td) / k_f``, where its deceleration ``k_f v`` equals ``a_b``: the demand's
deceleration is continuous and never above ``a_b``. Above the braking curve the law asks for
less than nothing and the lander coasts (falls freely, or under the parachute) until the curve
catches it: no fuel is spent on going slowly. Near the ground the tilt limit shrinks to
``touchdown_tilt`` so the lander touches upright.

Modes (``ControlOutput.mode``, forward only, so a mode never chatters): ``coast`` (the law asks for
less than a tenth of gravity; the attitude is held upright and the ground speed let be: without
thrust a tilt moves nothing, and under the chute chasing the wind with attitude alone only burnt
fuel, 20-70 kg of it in a first sweep), ``braking`` (on the braking limb), ``flare`` (on the
exponential limb). Requests: ``deploy_parachute`` once, when the lander is descending inside the atmosphere above
``chute_min_altitude`` and the chute would survive (predicted drag and airspeed under
``chute_margin`` of its limits): the chute takes kinetic energy away for nothing, which is fuel
saved on braking (scenario 1 cannot land without it: 176 m/s at the ground needs more than the
whole tank). ``landing_unreachable`` once, when the fuel left is less than the estimate of what
the rest of the descent needs (:meth:`LandingController.fuel_needed`).

Thruster failure (:mod:`.failure`): the law compares the measured body rates with the torque it
commanded and latches a thruster whose torque is missing (never reading the simulator's flags;
off under the parachute, whose torques swamp the residual). From then on it gives yaw up (the
demand heading follows the current one), allocates roll, pitch and lift exactly over the three
thrusters left (attitude first) and plans the braking on the lift they give without roll or pitch
torque (the diagonal pair's, half the four's). Measured limits: that lift is about the weight at
a full tank, and a tilt rate built before detection is taken out only once the yaw spin-up has
turned the body, so a failure near the ground ends in a harder but upright-er touchdown, not
yet a safe one (``test_landing_with_a_thruster_failed_mid_descent_touches_down_safely`` is xfail).
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ._params import matrix_param, positive_param
from .base import (
    REQUEST_DEPLOY_PARACHUTE,
    REQUEST_LANDING_UNREACHABLE,
    ControllerError,
    ControlOutput,
    Demand,
    Request,
)
from .failure import ThreeThrusterAllocation, ThrusterFailureDetector
from .ground_speed import GroundSpeedController

MODES = ("coast", "braking", "flare")


class LandingController(GroundSpeedController):
    """Lands: descent-rate profile + ground speed held at zero + parachute + fuel watch (module docstring).

    Parameters (SI): ``touchdown_rate`` ``v_td`` [m/s], ``flare_rate`` ``k_f`` [1/s],
    ``brake_fraction``, ``descent_gain`` ``k_v`` [1/s], ``touchdown_tilt`` [rad] (tilt limit at
    contact), ``tilt_height`` [m] (height over which the tilt limit shrinks to it), ``parachute``
    (use it), ``chute_min_altitude`` [m], ``chute_margin``, ``max_tilt``, ``velocity_poles``,
    ``attitude_poles``, ``design_fuel``.
    """

    name: ClassVar[str] = "landing"

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        touchdown_rate: float = 0.25,
        flare_rate: float = 0.3,
        brake_fraction: float = 0.5,
        descent_gain: float = 1.5,
        touchdown_tilt: float = 0.06,
        tilt_height: float = 20.0,
        parachute: bool = True,
        chute_min_altitude: float = 1000.0,
        chute_margin: float = 0.5,
        max_tilt: float = 0.7,
        velocity_poles: object = (-0.45, -0.5),
        attitude_poles: object = (-2.0,) * 6,
        design_fuel: float | None = None,
    ) -> None:
        super().__init__(
            vehicle, velocity_poles=velocity_poles, max_tilt=max_tilt, attitude_poles=attitude_poles, design_fuel=design_fuel
        )
        self.v_td = positive_param("touchdown_rate", touchdown_rate)
        self.k_f = positive_param("flare_rate", flare_rate)
        self.brake_fraction = positive_param("brake_fraction", brake_fraction)
        if self.brake_fraction >= 1.0:
            raise ControllerError(f"brake_fraction: expected a fraction in (0, 1), got {brake_fraction!r}")
        self.k_v = positive_param("descent_gain", descent_gain)
        self.touchdown_tilt = positive_param("touchdown_tilt", touchdown_tilt)
        self.tilt_height = positive_param("tilt_height", tilt_height)
        if not isinstance(parachute, (bool, np.bool_)):
            raise ControllerError(f"parachute: expected true or false, got {parachute!r}")
        self.use_parachute = bool(parachute)
        self.chute_min_altitude = float(matrix_param("chute_min_altitude", chute_min_altitude, ()))
        self.chute_margin = positive_param("chute_margin", chute_margin)
        self.half_size = 0.5 * vehicle.size
        self.mdot_max = sum(t.fuel_rate for t in vehicle.thrusters if t.enabled)  # [kg/s] at full throttle
        self._chute_k = 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2  # [m^2]
        self.failure_detector = ThrusterFailureDetector(vehicle)
        self._T_v_all = self.T_v
        self._mdot_all = self.mdot_max
        self.reset()

    def reset(self) -> None:
        super().reset()
        self.mode = MODES[0]
        self._chute_requested = False
        self._unreachable_raised = False
        self._mass = self.vehicle.mass(self.vehicle.fuel_capacity)
        if hasattr(self, "failure_detector"):
            self.failure_detector.reset()
            self.T_v = self._T_v_all
            self.mdot_max = self._mdot_all
        #: The allocation over the thrusters left once a failure is detected (None: all work).
        self.allocation: ThreeThrusterAllocation | None = None

    # --- profile ------------------------------------------------------------------------------

    def braking_acceleration(self, mass: float, g: float) -> float:
        """``a_b`` [m/s^2]: the planned braking deceleration at ``mass`` [kg] under gravity ``g``."""
        return self.brake_fraction * max(self.T_v / mass - g, 0.0)

    def descent_rate_demand(self, h_c: float, a_b: float) -> tuple[float, float, bool]:
        """``(v_d, dv_d/dh_c, on_flare_limb)`` at height above contact ``h_c`` [m] (v_d < 0: down)."""
        h_c = max(h_c, 0.0)
        v_x, h_x = self.flare_entry(a_b)
        if h_c <= h_x:
            return -(self.v_td + self.k_f * h_c), -self.k_f, True
        v = math.sqrt(v_x * v_x + 2.0 * a_b * (h_c - h_x))
        return -v, -a_b / v, False

    def flare_entry(self, a_b: float) -> tuple[float, float]:
        """Descent rate [m/s] and height [m] where the flare starts: the exponential limb decelerates
        at ``k_f v``, which equals the braking limb's ``a_b`` there, so the deceleration is continuous."""
        v_x = max(a_b / self.k_f, self.v_td)
        return v_x, (v_x - self.v_td) / self.k_f

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        a_b = self.braking_acceleration(self._mass, g)
        v_d, slope, flare = self.descent_rate_demand(h - self.half_size, a_b)
        a_up = g + self.k_v * (v_d - hd) + slope * hd
        stage = 2 if flare else (1 if a_up >= 0.1 * g else 0)
        if stage > MODES.index(self.mode):
            self.mode = MODES[stage]
        return a_up

    def tilt_limit(self, h: float) -> float:
        s = min(max((h - self.half_size) / self.tilt_height, 0.0), 1.0)
        return self.touchdown_tilt + s * (self.max_tilt - self.touchdown_tilt)

    def holds_ground_speed(self) -> bool:
        return self.mode != "coast"

    def velocity_demand(self, demand: Demand) -> tuple[float, float]:
        return (0.0, 0.0)

    # --- fuel and parachute -------------------------------------------------------------------

    def fuel_needed(self, h: float, hd: float, mass: float, chute: bool) -> float:
        """Estimate of the fuel [kg] the rest of the descent needs from height ``h`` [m], climb rate ``hd``.

        Falling freely (no drag) from ``(h_c, v0 = -hd)`` the lander meets the braking limb at
        speed ``v_m`` (with the chute: at most the chute's terminal speed at the surface). Braking
        from ``v_m`` to the flare entry ``v_x`` costs ``(v_m - v_x)(1 + g / a_b)`` (the second term
        is the gravity loss), the flare ``v_x - v_td + g t_flare``; the rocket equation with the
        vertical exhaust speed ``T_v / mdot_max`` turns that ``dv`` into fuel. Drag (which helps)
        and the attitude law's share (which costs) are both left out: from a 500 m hover the
        estimate is 33.5 kg against 32.9 kg flown (``test_fuel_estimate_matches_a_nominal_landing``).
        """
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        a_b = self.braking_acceleration(mass, g)
        if a_b <= 0.0:
            return math.inf
        h_c = max(h - self.half_size, 0.0)
        v0 = max(-hd, 0.0)
        v_x, h_x = self.flare_entry(a_b)
        # Free fall meets the braking limb v^2 = v_x^2 + 2 a_b (h - h_x) where v0^2 + 2 g (h_c - h) equals it.
        h_m = min(max((v0 * v0 + 2.0 * g * h_c - v_x * v_x + 2.0 * a_b * h_x) / (2.0 * (a_b + g)), h_x), h_c)
        v_m = math.sqrt(max(v_x * v_x + 2.0 * a_b * (h_m - h_x), 0.0))
        if chute:
            v_m = min(v_m, max(v_x, math.sqrt(mass * g / (self._chute_k * c.ATMOSPHERE_SURFACE_DENSITY))))
        h_flare = min(h_c, h_x)
        t_flare = math.log((self.v_td + self.k_f * h_flare) / self.v_td) / self.k_f
        dv = (v_m - v_x) * (1.0 + g / a_b) + (v_x - self.v_td) + g * t_flare
        c_v = self.T_v / self.mdot_max
        return mass * (1.0 - math.exp(-dv / c_v))

    def _chute_request(self, h: float, hd: float, speed: float) -> Request | None:
        if not self.use_parachute or self._chute_requested:
            return None
        if hd > -1.0 or h - self.half_size < self.chute_min_altitude or h >= c.EXOSPHERE_ALTITUDE:
            return None
        rho = c.ATMOSPHERE_SURFACE_DENSITY * math.exp(-h / c.ATMOSPHERE_SCALE_HEIGHT)
        drag = self._chute_k * rho * speed * speed
        if drag > self.chute_margin * c.PARACHUTE_MAX_DRAG or speed > self.chute_margin * c.PARACHUTE_MAX_SPEED:
            return None
        self._chute_requested = True
        return Request(
            REQUEST_DEPLOY_PARACHUTE,
            f"deploy the parachute at {h:.0f} m, {speed:.1f} m/s: predicted drag {drag:.0f} N "
            f"(limit {c.PARACHUTE_MAX_DRAG:.0f} N); it brakes the fall for no fuel",
            (("altitude", h), ("airspeed", speed), ("predicted_drag", drag)),
        )

    # --- thruster failure -----------------------------------------------------------------

    def _check_failure(self, t: float, state: StateView) -> None:
        if self.allocation is not None:
            return
        if self._chute_requested:
            # Under the canopy its restoring and damping torques (hundreds of N m at a few degrees
            # of tilt, against about 220 N m for a whole thruster) swamp the residual: no decision.
            self.failure_detector.reset()
            return
        i = self.failure_detector.observe(t, state.omega_B, state.fuel)
        if i is None:
            return
        self.allocation = ThreeThrusterAllocation(self.vehicle, i)
        # The profile's braking acceleration and the fuel estimate follow the lift that is left.
        self.T_v = self.allocation.max_lift
        self.mdot_max = sum(th.fuel_rate for j, th in enumerate(self.vehicle.thrusters) if th.enabled and j != i)

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray:
        if self.allocation is None:
            return L[0]
        return quat_to_matrix(state.q)[0]  # yaw given up: keep the current heading

    def mix(self, t: float, state: StateView, inner: Demand) -> np.ndarray:
        if self.allocation is None:
            return super().mix(t, state, inner)
        u_att = self.attitude.command(t, state, inner)
        torque = u_att @ self.allocation.tau  # what the attitude law asks of the four thrusters [N m]
        # Yaw is let be: only the roll and pitch torque are allocated (the lander spins up about its
        # axis, about 1 rad/s^2 with the pair near full throttle).
        u, saturated = self.allocation.allocate(torque[:2], self.lift_force)
        if saturated:
            self._mixed_from = u.copy()
        return u

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        self._mass = self.vehicle.mass(state.fuel)
        self._check_failure(t, state)
        out = super().update(t, state, demand)  # sets v_local (ENU velocity) and the mode
        self.failure_detector.commanded(out.throttles)
        h = float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS
        hd = float(self.v_local[2])
        requests: list[Request] = []
        chute = self._chute_request(h, hd, float(np.linalg.norm(state.v_W)))
        if chute is not None:
            requests.append(chute)
        if not self._unreachable_raised:
            need = self.fuel_needed(h, hd, self._mass, self._chute_requested or (
                self.use_parachute and h - self.half_size >= self.chute_min_altitude))
            if need > state.fuel:
                self._unreachable_raised = True
                requests.append(Request(
                    REQUEST_LANDING_UNREACHABLE,
                    f"safe landing out of reach: about {need:.1f} kg of fuel needed, {state.fuel:.1f} kg left",
                    (("fuel_needed", need), ("fuel_left", float(state.fuel)), ("altitude", h), ("climb_rate", hd)),
                ))
        return ControlOutput(out.throttles, out.saturated, out.unclipped, mode=self.mode, requests=tuple(requests))
