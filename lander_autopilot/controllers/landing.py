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
fuel, 20-70 kg a flight over a sweep of landings under the chute), ``braking`` (on the braking limb), ``flare`` (on the
exponential limb). Requests: ``deploy_parachute`` once, when the lander is descending inside the atmosphere above
``chute_min_altitude`` and the chute would survive (predicted drag and airspeed under
``chute_margin`` of its limits): the chute takes kinetic energy away for nothing, which is fuel
saved on braking (scenario 1 cannot land without it: 176 m/s at the ground needs more than the
whole tank). ``landing_unreachable`` once, when the fuel left is less than the estimate of what
the rest of the descent needs (:meth:`LandingController.fuel_needed`).

Thruster failure (:mod:`.failure`): the law compares the measured body rates with the torque it
commanded and latches a thruster whose torque is missing (never reading the simulator's flags).
Under the parachute the canopy's torque (hundreds of N m at a few degrees of tilt) is modelled,
with the wind learnt while the thrusters rest; coasting there the thrusters rest, so below
``probe_height`` a short probe burn (``probe_throttle`` on all four for ``probe_time`` every
``probe_period``) shows a dead one; braking under the canopy no decision is taken (the learnt
wind is then off by more than the check takes). Once a failure is known the law gives yaw up
(the demand heading follows the current one) and plans the braking on the lift that is left.

* Found without the canopy (a landing from a hover): roll, pitch and lift are allocated exactly
  over the three thrusters left (attitude first), the lift being the diagonal pair's (half the
  four's). A tilt rate built before detection is taken out only once the yaw spin-up has turned
  the body, so a failure near the ground ends in a harder landing
  (``test_landing_with_a_thruster_failed_mid_descent_touches_down_safely`` is xfail).
* Found under the canopy (scenario 1): the pair alone would have to brake from ~40 m/s with ~725 N
  against ~730 N of weight, ~30 s at full throttle, spinning the lander up to ~40 rad/s (the
  pair's yaw torques add). So the lander is spun up on purpose (pair at full to ``SPIN_MIN``)
  and flies the rest spinning at ``SPIN_RATE``: the lone thruster then lifts too (its roll/pitch
  torque turns with the body and only cones the axis), the yaw torque holds the spin, and the
  torque along the pair's axis precesses the spin axis to the thrust axis the ground-speed law
  asks for (:class:`.failure.SpinAllocation`). Over the last ``LONE_HEIGHT`` the lone thruster
  gives way to the pair, so the cone, and the touchdown tilt, shrink.
"""
from __future__ import annotations

import math
from typing import ClassVar, Protocol

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from .base import (
    REQUEST_DEPLOY_PARACHUTE,
    REQUEST_LANDING_UNREACHABLE,
    ControlOutput,
    Demand,
    Request,
)
from .combined import Mix
from .failure import ChuteTorqueModel, SpinAllocation, ThreeThrusterAllocation, ThrusterFailureDetector
from .ground_speed import GroundSpeedController
from .params import Param, ParamTable, boolean, finite, fraction_open, positive

MODES = ("coast", "braking", "flare")

#: The descent laws leave their coast mode once they ask for a thrust acceleration along up of at
#: least this fraction of gravity [-]: under it the thrust would tilt nothing (module docstring),
#: and a law coasting above its braking curve asks for less than nothing.
COAST_THRESHOLD_G = 0.1

#: [s] the control period assumed until two updates have measured it: the autopilot's 10 Hz
NOMINAL_CONTROL_PERIOD = 0.1
#: [s] slack on the probe burn's clock (control instants ``k * period`` carry rounding of ~1e-12 s):
#: a burn due at an instant starts at it, not a period late
CLOCK_SLACK = 1e-9
#: [rad] half-turns of the body per period under which the turning torque's mean (sinc) is taken as
#: whole: sinc's error there is ~1e-19
SINC_SMALL = 1e-9
#: [-] floor of the sinc the spinning law divides the torque by: it reaches 0.3 at a half-turn of
#: ~2.4 rad a period (a 47 rad/s spin at 0.1 s, well over SPIN_MAX), so it never binds in a held spin and only
#: keeps the torque asked finite (at most 3.3 x) as the mean of a turning torque goes to zero
SINC_FLOOR = 0.3

#: [m^2] ``1/2 Cd A`` of the open canopy: its drag is ``CHUTE_DRAG_K rho v^2``
CHUTE_DRAG_K = 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2


class DescentProfile(Protocol):
    """A part that flies the landing law's loops to another end than a touchdown (the de-orbit's
    braking to a hover, :class:`.deorbit.DescentToAltitude`), handed to :class:`LandingController`
    as ``profile``. The law asks it at each of its steps; a method that returns None leaves that
    step to the landing law's own. It reads and sets the law through the law's public members."""

    #: whether the law watches for a failed thruster (and probes the coast under the canopy for one)
    detects_failures: bool

    def braking_acceleration(self, mass: float, g: float) -> float:
        """The planned braking deceleration [m/s^2] at ``mass`` [kg] under gravity ``g`` [m/s^2]."""
        ...

    def vertical_acceleration(self, t: float, h: float, hd: float, demand: Demand) -> float:
        """Thrust acceleration along up [m/s^2] at altitude ``h`` [m], climb rate ``hd`` [m/s]; sets the law's mode."""
        ...

    def tilt_limit(self, h: float) -> float | None:
        """Largest tilt of the thrust from the vertical [rad] at altitude ``h``; None: the law's."""
        ...

    def horizontal_acceleration(self, state: StateView, L: np.ndarray, h: float, v_L: np.ndarray,
                                error: np.ndarray) -> np.ndarray | None:
        """Horizontal thrust acceleration, ENU [m/s^2] (the ground-speed law's hook); None: the law's PI."""
        ...

    def axis_bias(self, t: float, state: StateView, L: np.ndarray, wanted: np.ndarray) -> np.ndarray | None:
        """A correction to the thrust axis (the ground-speed law's hook); None: none."""
        ...

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray | None:
        """World vector the demand body x is kept nearest to; None: the law's."""
        ...

    def mixed(self, m: Mix) -> None:
        """Told each step's mix (the throttles before clipping and whether the mixer gave way)."""
        ...


class LandingController(GroundSpeedController):
    """Lands: descent-rate profile + ground speed held at zero + parachute + fuel watch (module docstring).

    Parameters: the table :attr:`PARAMS` (``lander controllers landing``; ``v_td``, ``k_f``, ``k_v``
    are ``touchdown_rate``, ``flare_rate``, ``descent_gain``). The spinning descent's settings are
    class attributes (``SPIN_MIN`` ... ``LONE_TOUCHDOWN``), each with the measurement that chose it.
    """

    name: ClassVar[str] = "landing"

    PARAMS: ClassVar[ParamTable] = ParamTable((
        Param("touchdown_rate", 0.25, "m/s", "> 0", "descent rate at contact (the flare limb's end)", positive),
        Param("flare_rate", 0.3, "1/s", "> 0", "the flare limb's exponential rate: its descent rate falls by this per metre",
              positive),
        Param("brake_fraction", 0.5, "-", "(0, 1)",
              "braking limb's deceleration, of the net thrust (the rest: margin for thrust and mass errors)",
              fraction_open),
        Param("descent_gain", 1.5, "1/s", "> 0", "gain of the descent-rate loop", positive),
        Param("touchdown_tilt", 0.06, "rad", "> 0", "tilt limit at contact", positive),
        Param("tilt_height", 20.0, "m", "> 0", "height above contact over which the tilt limit shrinks to it", positive),
        Param("parachute", True, "-", "true, false", "ask for the chute when it would survive", boolean),
        Param("chute_min_altitude", 1000.0, "m", "finite", "lowest height above contact the chute is asked for at",
              finite),
        Param("chute_margin", 0.5, "-", "> 0", "fraction of the canopy's airspeed and drag limits it is opened within",
              positive),
        Param("probe_height", 2000.0, "m", "finite",
              "height above contact below which the coast under the canopy is probed for a dead thruster (0: never)",
              finite),
        Param("probe_throttle", 0.25, "-", "> 0", "probe burn's throttle, added on every thruster", positive),
        Param("probe_period", 2.0, "s", "> 0", "time between probe burns", positive),
        Param("probe_time", 0.3, "s", "> 0", "length of a probe burn", positive),
        # the ground-speed law's (the horizontal loop and the attitude law are its)
        *(GroundSpeedController.PARAMS[k] for k in ("max_tilt", "velocity_poles", "attitude_poles", "design_fuel")),
    ))

    def __init__(self, vehicle: Vehicle, profile: DescentProfile | None = None, **params: object) -> None:
        p = self.PARAMS.resolve(params, self.name)
        #: The part flying the law to another end (:class:`DescentProfile`); None: a landing.
        self.profile = profile
        #: Watch for a failed thruster (and probe the coast under the canopy for one); a profile whose
        #: flight the watch cannot read switches it off (:class:`..deorbit.DescentToAltitude`).
        self.detects_failures = True if profile is None else profile.detects_failures
        super().__init__(
            vehicle, velocity_poles=p["velocity_poles"], max_tilt=p["max_tilt"], attitude_poles=p["attitude_poles"],  # type: ignore[arg-type]
            design_fuel=p["design_fuel"],  # type: ignore[arg-type]
        )
        self.v_td = float(p["touchdown_rate"])  # type: ignore[arg-type]  # each checked by its row
        self.k_f = float(p["flare_rate"])  # type: ignore[arg-type]
        self.brake_fraction = float(p["brake_fraction"])  # type: ignore[arg-type]
        self.k_v = float(p["descent_gain"])  # type: ignore[arg-type]
        self.touchdown_tilt = float(p["touchdown_tilt"])  # type: ignore[arg-type]
        self.tilt_height = float(p["tilt_height"])  # type: ignore[arg-type]
        self.use_parachute = bool(p["parachute"])
        self.chute_min_altitude = float(p["chute_min_altitude"])  # type: ignore[arg-type]
        self.chute_margin = float(p["chute_margin"])  # type: ignore[arg-type]
        self.half_size = 0.5 * vehicle.size
        self.mdot_max = sum(t.fuel_rate for t in vehicle.thrusters if t.enabled)  # [kg/s] at full throttle
        self._chute_k = CHUTE_DRAG_K
        self.probe_height = float(p["probe_height"])  # type: ignore[arg-type]
        self.probe_throttle = float(p["probe_throttle"])  # type: ignore[arg-type]
        self.probe_period = float(p["probe_period"])  # type: ignore[arg-type]
        self.probe_time = float(p["probe_time"])  # type: ignore[arg-type]
        self.failure_detector = ThrusterFailureDetector(vehicle)
        self.chute_model = ChuteTorqueModel(vehicle)
        self._T_v_all = self.T_v
        self._mdot_all = self.mdot_max
        self.reset()

    def reset(self) -> None:
        super().reset()
        self.mode = MODES[0]
        self._chute_requested = False
        self._unreachable_raised = False
        # true density / modelled density, where an entry law has measured it (DeorbitController); the
        # chute's predicted drag uses it: +30 % of air tore the canopy off at 0.9 of the modelled limit
        self.density_scale = 1.0
        self._mass = self.vehicle.mass(self.vehicle.fuel_capacity)
        if hasattr(self, "failure_detector"):
            self.failure_detector.reset()
            self.chute_model.reset()
            self.T_v = self._T_v_all
            self.mdot_max = self._mdot_all
        #: The allocation over the thrusters left once a failure is detected (None: all work).
        self.allocation: ThreeThrusterAllocation | None = None
        self._h_c = math.inf  # height above contact [m] the profile last saw
        self._t_prev: float | None = None
        self._probe_start: float | None = None
        #: Set when the failure is found under the canopy: the rest of the descent is flown spinning.
        self.spin: SpinAllocation | None = None
        self._spinning = False
        self._dt = NOMINAL_CONTROL_PERIOD  # [s] control period, measured between updates

    @property
    def mass(self) -> float:
        """The mass [kg] the law plans with: the vehicle's at the last update (a full tank before one).
        Set it to evaluate the law's design (its braking, its scheduled gain) at another mass."""
        return self._mass

    @mass.setter
    def mass(self, value: float) -> None:
        self._mass = float(value)

    @property
    def control_period(self) -> float:
        """The control period [s], measured between the last two updates (0.1 s before two)."""
        return self._dt

    # --- profile ------------------------------------------------------------------------------

    def braking_acceleration(self, mass: float, g: float) -> float:
        """``a_b`` [m/s^2]: the planned braking deceleration at ``mass`` [kg] under gravity ``g``
        (the profile's, if one flies the law)."""
        if self.profile is not None:
            return self.profile.braking_acceleration(mass, g)
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
        if self.profile is not None:
            return self.profile.vertical_acceleration(t, h, hd, demand)
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        a_b = self.braking_acceleration(self._mass, g)
        self._h_c = h - self.half_size
        v_d, slope, flare = self.descent_rate_demand(h - self.half_size, a_b)
        a_up = g + self.k_v * (v_d - hd) + slope * hd
        stage = 2 if flare else (1 if a_up >= COAST_THRESHOLD_G * g else 0)
        if stage > MODES.index(self.mode):
            self.mode = MODES[stage]
        return a_up

    def tilt_limit(self, h: float) -> float:
        if self.profile is not None:
            lim = self.profile.tilt_limit(h)
            if lim is not None:
                return lim
        s = min(max((h - self.half_size) / self.tilt_height, 0.0), 1.0)
        return self.touchdown_tilt + s * (self.max_tilt - self.touchdown_tilt)

    def holds_ground_speed(self) -> bool:
        return self.mode != "coast"

    def velocity_demand(self, demand: Demand) -> tuple[float, float]:
        return (0.0, 0.0)

    def horizontal_acceleration(self, state: StateView, L: np.ndarray, h: float, v_L: np.ndarray,
                                error: np.ndarray) -> np.ndarray:
        if self.profile is not None:
            a_h = self.profile.horizontal_acceleration(state, L, h, v_L, error)
            if a_h is not None:
                return a_h
        return super().horizontal_acceleration(state, L, h, v_L, error)

    def axis_bias(self, t: float, state: StateView, L: np.ndarray, wanted: np.ndarray) -> np.ndarray | None:
        return None if self.profile is None else self.profile.axis_bias(t, state, L, wanted)

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

    @property
    def chute_requested(self) -> bool:
        """True once the law has asked for the chute (or been told it is out)."""
        return self._chute_requested

    def assume_chute_requested(self, requested: bool) -> None:
        """Start as if the chute had (or had not) been asked for: a flight begun under the open chute
        must not ask again, and its failure watch models the canopy."""
        self._chute_requested = bool(requested)

    def rearm_unreachable(self) -> None:
        """Let the ``landing_unreachable`` request be raised again (a caller that withheld it)."""
        self._unreachable_raised = False

    def chute_request(self, h: float, hd: float, speed: float) -> Request | None:
        """The ``deploy_parachute`` request, once: descending (``hd`` [m/s] under -1) inside the
        atmosphere at altitude ``h`` [m] above ``chute_min_altitude`` over contact, with the chute's
        predicted drag and airspeed ``speed`` [m/s] under ``chute_margin`` of its limits; else None."""
        if not self.use_parachute or self._chute_requested:
            return None
        if hd > -1.0 or h - self.half_size < self.chute_min_altitude or h >= c.EXOSPHERE_ALTITUDE:
            return None
        drag = self._chute_k * self.density_scale * MARS_ATMOSPHERE.density(h) * speed * speed
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
        if self.allocation is not None or not self.detects_failures:
            return
        dt = 0.0 if self._t_prev is None else t - self._t_prev
        if self._chute_requested and self.mode != "coast":
            # Braking under the canopy the model's wind, learnt while coasting, is off by more than
            # the check can take (5 false alarms in 60 dispersed flights): no decision there.
            self.failure_detector.reset()
            return
        # Under the canopy its torque (hundreds of N m at a few degrees of tilt, against about
        # 220 N m for a whole thruster) is modelled, with the wind learnt while the thrusters rest.
        ext = self.chute_model.torque(state) if self._chute_requested else None
        i = self.failure_detector.observe(t, state.omega_B, state.fuel, ext)
        if self._chute_requested:
            self.chute_model.learn(self.failure_detector.residual, self.failure_detector.residual_throttles, state, dt)
        if i is None:
            return
        self.allocation = ThreeThrusterAllocation(self.vehicle, i)
        # The profile's braking acceleration and the fuel estimate follow the lift that is left.
        self.T_v = self.allocation.max_lift
        self.mdot_max = sum(th.fuel_rate for j, th in enumerate(self.vehicle.thrusters) if th.enabled and j != i)
        if self._chute_requested:
            self.spin = SpinAllocation(self.vehicle, i)
            # Spinning, the lift runs from the two thrusters' worth the spin can be held at (zero yaw
            # torque) to the three's (the spin then grows): plan the braking half way.
            self.T_v = 0.5 * (self.spin.max_lift_no_yaw + self.spin.max_lift)

    def _probing(self, t: float) -> bool:
        """True while a probe burn is on (every ``probe_period`` s, ``probe_time`` s long): coasting
        under the canopy below ``probe_height`` with no failure known, the thrusters rest, so a dead
        one would stay unseen until the braking, too late to plan for the lift that is left."""
        if (self.allocation is not None or not self.detects_failures or not self._chute_requested or self.mode != "coast"
                or self._h_c > self.probe_height):
            self._probe_start = None
            return False
        if self._probe_start is None or t - self._probe_start >= self.probe_period - CLOCK_SLACK:
            self._probe_start = t
        return t - self._probe_start < self.probe_time - CLOCK_SLACK

    def heading_axis(self, state: StateView, L: np.ndarray) -> np.ndarray:
        if self.profile is not None:
            axis = self.profile.heading_axis(state, L)
            if axis is not None:
                return axis
        if self.allocation is None:
            return super().heading_axis(state, L)
        return quat_to_matrix(state.q)[0]  # yaw given up: keep the current heading

    # Spinning descent after a failure found under the canopy (module docstring, docs/control.md).
    #: [rad/s] spin at which the spinning law takes over from the three-thruster one (the pair at full
    #: throttle spins the lander up at ~1.4 rad/s^2, so ~4 s after the failure is found).
    SPIN_MIN = 6.0
    #: [rad/s] spin held while the lone thruster can fire. The lone thruster's cone is
    #: tau_L u_L / ((I_t - I_z) Omega^2), 4 deg at full throttle here; faster spins turn the body more
    #: than 1 rad per 0.1 s control period (and simulator step). Of the 6 sweep cases with a failure
    #: under the canopy, 8, 9, 10, 12 rad/s landed 1, 2, 5, 2 (precession 2 /s, no lone cap); 15: 0.
    SPIN_RATE = 10.0
    #: [rad/s] above this the spin is held before the lift (flown, a lander spun up by the pair
    #: alone stayed within 6 deg up to 20 rad/s; from ~28 rad/s the simulator's 0.1 s step diverged).
    SPIN_MAX = 18.0
    #: [1/s] rate at which the yaw torque brings the spin back to SPIN_RATE.
    SPIN_GAIN = 0.5
    #: [1/s] rate at which the spin axis (the angular momentum's direction) is steered to the thrust
    #: axis the ground-speed law asks for: at 10 rad/s and no lone cap 1.5, 2, 3 /s landed 4, 5, 2 of
    #: the 6; with the cap below, 1.5 /s landed all 6.
    PRECESSION_RATE = 1.5
    #: [m] over the last LONE_HEIGHT above contact the lone thruster's throttle is capped, from 1 down
    #: to LONE_TOUCHDOWN at contact: the pair takes the lift, the spin grows and the cone (which sets
    #: the touchdown tilt) shrinks; slowly, so that no nutation starts. (20 m, 0.5): 6 of the 6 and
    #: 58 of 60 dispersed flights with a failure drawn in the coast; (30, 0.3) 4 of 6; (50, 0) 1 of 6.
    LONE_HEIGHT = 20.0
    LONE_TOUCHDOWN = 0.5

    def _spin_mix(self, state: StateView) -> Mix:
        """Throttles of the spinning descent: lift from the profile, yaw torque holding the spin,
        and the roll/pitch torque along the pair's axis that precesses the spin axis (body frame)."""
        spin = self.spin
        assert spin is not None
        R = quat_to_matrix(state.q)  # rows: body axes in world coordinates
        I = self.vehicle.inertia(state.fuel)
        w = np.asarray(state.omega_B, dtype=float)
        L_B = I * w  # angular momentum, body frame [N m s]
        L_z = float(L_B[2])
        # The spin axis: the angular momentum's direction, world frame. The body axis cones about it
        # (the lone thruster's torque, nutation); steering it steers the mean thrust.
        a = R.T @ (L_B / L_z)
        a /= float(np.linalg.norm(a))
        e = self.thrust_axis_W - float(self.thrust_axis_W @ a) * a
        # dL/dt = tau, L = L_z a: the torque L_z k e turns a towards the wanted axis at rate k.
        tau_B = R @ (L_z * self.PRECESSION_RATE * e)
        # The throttles hold for a period while the body turns Omega dt: ask in the body axes of
        # mid-period (the world torque seen from the body turns by -Omega t) and for the loss of
        # the mean of a turning torque (sinc).
        half = 0.5 * float(w[2]) * self._dt
        c_, s_ = math.cos(-half), math.sin(-half)
        txy = np.array([c_ * tau_B[0] - s_ * tau_B[1], s_ * tau_B[0] + c_ * tau_B[1]])
        sinc = math.sin(half) / half if abs(half) > SINC_SMALL else 1.0
        tau_p = float(txy @ spin.e_P) / max(sinc, SINC_FLOOR)
        yaw = -float(I[2]) * self.SPIN_GAIN * (float(w[2]) - spin.pair_spin * self.SPIN_RATE)
        s_h = min(max(self._h_c / self.LONE_HEIGHT, 0.0), 1.0)
        lone_max = self.LONE_TOUCHDOWN + s_h * (1.0 - self.LONE_TOUCHDOWN)
        u, saturated = spin.allocate(tau_p, self.lift_force, yaw, yaw_first=abs(float(w[2])) > self.SPIN_MAX,
                                     lone_max=lone_max)
        return Mix(u, mixed_from=u.copy() if saturated else None)

    def mix(self, t: float, state: StateView, inner: Demand) -> Mix:
        m = self._allocated_mix(t, state, inner)
        if self.profile is not None:
            self.profile.mixed(m)
        return m

    def _allocated_mix(self, t: float, state: StateView, inner: Demand) -> Mix:
        """The mix over the thrusters that work: all four's, or the allocation's once one failed."""
        if self.allocation is None:
            return super().mix(t, state, inner)
        lift = self.lift_force
        if self.spin is not None:
            if self._spinning or abs(float(state.omega_B[2])) >= self.SPIN_MIN:
                self._spinning = True
                return self._spin_mix(state)
            lift = max(lift, self.allocation.max_lift)  # spin up with the pair at full
        u_att = self.attitude.command(t, state, inner)
        torque = u_att @ self.allocation.tau  # what the attitude law asks of the four thrusters [N m]
        # Yaw is let be: only the roll and pitch torque are allocated (the lander spins up about its
        # axis, about 1 rad/s^2 with the pair near full throttle).
        u, saturated = self.allocation.allocate(torque[:2], lift)
        return Mix(u, mixed_from=u.copy() if saturated else None)

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        self._mass = self.vehicle.mass(state.fuel)
        self._check_failure(t, state)
        out = super().update(t, state, demand)  # sets v_local (ENU velocity) and the mode
        if self._probing(t):
            # The same throttle added on every thruster: no torque if all work, a dead one's whole
            # share of it if one does not.
            u = np.clip(out.throttles + self.probe_throttle, 0.0, 1.0)
            out = ControlOutput(u, out.saturated, out.unclipped, mode=out.mode)
        self.failure_detector.commanded(out.throttles)
        if self._t_prev is not None and t > self._t_prev:
            self._dt = t - self._t_prev
        self._t_prev = t
        h = float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS
        hd = float(self.v_local[2])
        requests: list[Request] = []
        chute = self.chute_request(h, hd, float(np.linalg.norm(state.v_W)))
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
