"""Online estimation for the de-orbit law: the thrust, the air's density and the drag, measured
from the flight itself, a control period at a time.

Each period's acceleration is the difference of two velocities a period apart, minus gravity
(known) and the thrust the law commanded over the period (known to the law): what is left is the
quantity measured (:mod:`..calibration` for the fits). Core code (no rclpy), world frame, SI units.

* the de-orbit burn, in vacuum: the thrust per modelled mass (:meth:`OnlineEstimator.learn_thrust`);
* the entry, chute packed: the density over the model's (:meth:`OnlineEstimator.learn_density`),
  which the chute's predicted drag uses;
* under the open chute, thrusters off: the drag's scale (:meth:`OnlineEstimator.learn_drag`) for
  the braking limb's curve, and the fit of the scale and the wind over the whole coast
  (:meth:`OnlineEstimator.fit_air`, at the powered descent's start).
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

from ..calibration import AirFit, ChuteDragFit, ThrustCalibration
from .descent import DescentToAltitude
from .geometry import altitude, climb_rate, norm3

#: [-] bounds of one period's measured-over-modelled ratio (density, drag) before it is filtered:
#: one period dominated by a gust or the canopy's opening jerk moves the estimate a bounded step,
#: while the dispersions the laws are built for (density +-30 %, drag coefficient and mass a few
#: per cent) lie well inside a factor 3 either way.
RATIO_BOUNDS = (0.3, 3.0)
#: [s] time constant of the density and drag-scale filters: about 20 control periods, so the noise
#: of differenced velocities averages out, and short against the ~100 s under the chute.
FILTER_TIME = 2.0
#: [-] largest axial thrust, of ``T_v``, of a coasting period the density is learnt from: the
#: attitude hold commands a few per cent; a braking entry's thrust would swamp the drag measured.
COAST_THRUST_SHARE = 0.05
#: [m/s^2] smallest modelled drag deceleration the density is learnt at: under it the difference
#: of two velocities a period apart is mostly noise.
MIN_MODEL_DRAG = 0.5
#: [m/s] smallest fall speed under the chute at which its drag scale is learnt: slower, the drag
#: (as its square) is too small against the noise of differenced climb rates.
MIN_FALL_SPEED = 5.0


def clamp_ratio(ratio: float) -> float:
    """``ratio`` within :data:`RATIO_BOUNDS`."""
    return min(max(ratio, RATIO_BOUNDS[0]), RATIO_BOUNDS[1])


class OnlineEstimator:
    """The de-orbit law's measurements of its models; ``drag_k`` [m^2] is ``sum 1/2 Cd A`` of canopy
    and body (the drag once the chute is out). :meth:`reset` forgets every measurement."""

    def __init__(self, vehicle: Vehicle, drag_k: float) -> None:
        self.vehicle = vehicle
        self.drag_k = drag_k
        self.reset()

    def reset(self) -> None:
        self.thrust_calibration = ThrustCalibration()
        self.air_fit = ChuteDragFit()
        self.air: AirFit | None = None  # the fit at the powered descent's start (fit_air)
        self._last_climb: tuple[float, float] | None = None
        self._last_coast: tuple[float, np.ndarray] | None = None  # (t, v_W) at the last entry period
        self._coast_thrust = math.inf  # axial thrust [N] commanded over the period since
        self._last_air: tuple[float, np.ndarray, np.ndarray, float] | None = None  # (t, v_W, r_W, fuel)
        self._coast_thrust_W = np.zeros(3)  # thrust [N, world] commanded over the period since
        self._last_burn: tuple[float, np.ndarray, np.ndarray, float, float] | None = None  # (t, v_W, g_W, fuel, thrust)

    def learn_thrust(self, t: float, state: StateView, thrust: float) -> None:
        """De-orbit burn: one period's measured thrust acceleration against the model's
        (:class:`..calibration.ThrustCalibration`); ``thrust`` [N] is the axial thrust commanded for
        the period starting now. Both laws fly the powered descent on the scale: the MPC plans on it
        (``deorbit-mpc``), the scheduled law's ``T_v`` is scaled by it at the handover."""
        rn = float(np.linalg.norm(state.r_W))
        g_W = -c.GM_MARS * np.asarray(state.r_W, float) / rn**3
        prev = self._last_burn
        if prev is not None and t > prev[0] and prev[4] > 0.0:
            dt = t - prev[0]
            mass = 0.5 * (self.vehicle.mass(prev[3]) + self.vehicle.mass(state.fuel))
            self.thrust_calibration.add((state.v_W - prev[1]) / dt, 0.5 * (g_W + prev[2]), prev[4], mass)
        self._last_burn = (t, np.array(state.v_W, float), g_W, float(state.fuel), thrust)

    def entry_thrust(self, thrust: float) -> None:
        """Entry, chute packed: the axial thrust [N] commanded for the period starting now."""
        self._coast_thrust = thrust

    def chute_thrust(self, thrust_W: np.ndarray) -> None:
        """Under the open chute: the thrust [N, world] commanded for the period starting now."""
        self._coast_thrust_W = thrust_W

    def learn_density(self, t: float, state: StateView, descent: DescentToAltitude) -> None:
        """Entry, chute packed, coasting: the air's density against the model's, for the chute.

        Over a period ``v' = g_W + a_D + a_T``, ``|a_D| = k_body rho |v|^2 / m``, the thrust axis held
        retrograde, so ``|a_D| ~ |dv/dt - g_W| - T / m`` with ``T`` the axial thrust the attitude hold
        commanded (periods with more than ``COAST_THRUST_SHARE`` of ``T_v``, a braking entry, are
        skipped). The measured over the model's gives ``rho_true / rho_model`` (filtered over
        ``FILTER_TIME``; only where the model's drag exceeds ``MIN_MODEL_DRAG``), into the descent
        law's ``density_scale``, which the chute's predicted drag uses: with +30 % of air a canopy
        opened at 0.9 of its modelled drag limit is torn off."""
        prev, self._last_coast = self._last_coast, (t, np.array(state.v_W, float))
        thrust, self._coast_thrust = self._coast_thrust, math.inf
        if prev is None or t <= prev[0] or thrust > COAST_THRUST_SHARE * descent.law.T_v:
            return
        h = altitude(state)
        rn = norm3(state.r_W)
        speed2 = float(state.v_W @ state.v_W)
        mass = self.vehicle.mass(state.fuel)
        model = 0.5 * c.SPHERE_DRAG_COEFFICIENT * c.SPHERE_DRAG_AREA * MARS_ATMOSPHERE.density(h) * speed2 / mass
        if model < MIN_MODEL_DRAG:
            return
        measured = norm3((state.v_W - prev[1]) / (t - prev[0]) + c.GM_MARS * state.r_W / rn**3) - thrust / mass
        ratio = clamp_ratio(measured / model)
        descent.law.density_scale += min((t - prev[0]) / FILTER_TIME, 1.0) * (ratio - descent.law.density_scale)

    def learn_drag(self, t: float, state: StateView, descent: DescentToAltitude) -> None:
        """Under the open chute with the thrusters off: the drag the air really gives against the model's.

        Vertically ``h'' = -g + c_true h'^2`` with no thrust, so each period's measured acceleration
        (difference of climb rates) gives ``c_true / c_model = (h'' + g) / (c_model h'^2)``; filtered
        over ``FILTER_TIME`` into the descent law's ``drag_scale``. It folds a density, a drag
        coefficient or a mass off the model into one number, which the braking limb then uses:
        without it a 30 % thinner atmosphere than modelled leaves the limb ~1 m/s^2 short of its
        deceleration near the chute's terminal speed, five times the law's thrust margin, and the
        lander brakes tens of metres past the hover altitude.

        Each period also gives the fit of the drag's scale and the wind over the whole coast
        (:class:`..calibration.ChuteDragFit`, solved at the powered descent's start, :meth:`fit_air`):
        the measured drag vector, the thrust commanded over the period taken off. The scalar sets the
        limb's curve until the fit, the braking's first instant included."""
        h = altitude(state)
        climb = climb_rate(state)
        prev, self._last_climb = self._last_climb, (t, climb)
        before, self._last_air = self._last_air, (t, np.array(state.v_W, float), np.array(state.r_W, float), float(state.fuel))
        if before is not None and t > before[0]:
            dt = t - before[0]
            r_mid = 0.5 * (state.r_W + before[2])
            rn = float(np.linalg.norm(r_mid))
            mass = self.vehicle.mass(0.5 * (state.fuel + before[3]))
            drag_W = (state.v_W - before[1]) / dt + c.GM_MARS * r_mid / rn**3 - self._coast_thrust_W / mass
            k = self.drag_k * MARS_ATMOSPHERE.density(rn - c.MARS_RADIUS) / mass
            self.air_fit.add(0.5 * (state.v_W + before[1]), drag_W, k)
        if prev is None or t <= prev[0] or climb > -MIN_FALL_SPEED:
            return
        r = c.MARS_RADIUS + h
        g = c.GM_MARS / (r * r)
        c_model = self.drag_k * MARS_ATMOSPHERE.density(h) / self.vehicle.mass(state.fuel)
        ratio = ((climb - prev[1]) / (t - prev[0]) + g) / (c_model * climb * climb)
        ratio = clamp_ratio(ratio)
        descent.drag_scale += min((t - prev[0]) / FILTER_TIME, 1.0) * (ratio - descent.drag_scale)

    def fit_air(self, state: StateView, descent: DescentToAltitude) -> None:
        """At the powered descent's start: the density scale and mean wind over the coast under the
        chute (:class:`..calibration.ChuteDragFit`), from the scale learnt and the drift as first
        guess; the descent law brakes in that air (its ``air``, ``drift_W``, ``wind_h``, ``wind_up``)."""
        up = state.r_W / float(np.linalg.norm(state.r_W))
        drift = state.v_W - float(state.v_W @ up) * up
        self.air = self.air_fit.solve(descent.drag_scale, drift)
        descent.air = self.air
        descent.drift_W = drift
        w = descent.wind_W
        descent.wind_h = float(np.linalg.norm(w - float(w @ up) * up))
        descent.wind_up = float(w @ up)  # read only with a fit (without one, w is the horizontal drift)
