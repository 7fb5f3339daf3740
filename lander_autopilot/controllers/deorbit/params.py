"""The parameter tables of the de-orbit laws ``deorbit`` and ``deorbit-mpc`` (:mod:`..params`).

The two share the mission's rows (the same :class:`..params.Param` objects); each adds the rows
of its powered descent. ``lander controllers deorbit`` prints a table; docs/deorbit.md carries
them generated (``lander controllers --update-docs``).
"""
from __future__ import annotations

from ...guidance.deorbit import CHUTE_ALTITUDE, SLEW_TIME
from ...guidance.descent_mpc import MIN_TIME_TO_GO
from ..params import (
    PI_2,
    Param,
    ParamTable,
    angle_in,
    at_most,
    boolean,
    design_fuel,
    fraction,
    fraction_open,
    integer_at_least,
    negative,
    non_negative,
    optional,
    poles,
    positive,
    share,
)
from .descent import BRAKING_LAG, BRAKING_SETTLE, STOP_ABOVE
from .geometry import AXIS_LIMIT
from .hover import HOVER_ATTITUDE_POLES, HOVER_BAND, HOVER_SPEED
from .mpc import ATTITUDE_LAG, AXIS_TIME, COAST_COLLECTIVE, MAX_TILT

#: Rows of the mission itself, both laws' (the phases before and after the powered descent).
MISSION_ROWS: tuple[Param, ...] = (
    Param("slew_time", SLEW_TIME, "s", "> 0", "time before the de-orbit burn may start, to turn the thrust axis retrograde",
          positive),
    Param("navigation_velocity_sigma", 0.0, "m/s", ">= 0",
          "velocity error (1 sigma/axis) of the state the burn is planned from: no waiting for an apoapsis it made (0: truth)",
          non_negative),
    Param("navigation_position_sigma", 0.0, "m", ">= 0",
          "position error (1 sigma/axis) of the state the burn is planned from (0: the truth)", non_negative),
    Param("burn_throttle", 0.85, "-", "> 0",
          "collective throttle of the de-orbit burn (and of an entry that must brake); the rest is the attitude law's",
          positive),
    Param("hover_band", HOVER_BAND, "m", "> 0", "the powered descent hands over to the hover within this of the demand altitude",
          positive),
    Param("hover_speed", HOVER_SPEED, "m/s", "> 0", "... at a climb rate within this of zero", positive),
    Param("chute_first", True, "-", "true, false",
          "coast for the chute (no thrust until it opens and while it brakes harder than the braking limb)", boolean),
    Param("chute_margin", 0.9, "-", "(0, 1]",
          "fraction of the canopy's airspeed and drag limits the chute is opened within", fraction),
    Param("chute_altitude", CHUTE_ALTITUDE, "m", "> 0", "lowest planned and predicted chute opening", positive),
    Param("predict_every", 1.0, "s", "> 0", "period of the entry's drag-only prediction (chute packed)", positive),
    Param("attitude_poles", (-1.0,) * 6, "1/s", "6 poles, Re < 0",
          "the quaternion attitude law's poles from the slew to the parachute", poles(6)),
    Param("hover_attitude_poles", HOVER_ATTITUDE_POLES, "1/s", "6 poles, Re < 0",
          "the hover's attitude poles: the tilt the wind needs at rest flown before the drift grows", poles(6)),
    Param("design_fuel", None, "kg", "none or > 0", "fuel the attitude law is designed at (none: a full tank)",
          design_fuel),
    Param("land_after_hover", None, "s", "none or > 0",
          "land (the `landing` phase, as on demand altitude 0) once the hover is held this long in its band (none: never)",
          optional(positive)),
)

#: Rows of the scheduled powered descent (``deorbit``).
SCHEDULED_ROWS: tuple[Param, ...] = (
    Param("brake_fraction", 0.96, "-", "(0, 1)",
          "braking limb's deceleration, of the net thrust the attitude law leaves (the rest: feedback margin)",
          fraction_open),
    Param("stop_above", STOP_ABOVE, "m", "[0, hover_band)",
          "the braking limb ends at rest this far over the demand: a braking that falls behind stops in the band",
          non_negative),
    Param("descent_pole", -2.0, "1/s", "< 0", "pole of the descent's velocity loop, its gain scheduled over mass and drag",
          negative),
    Param("braking_lag", BRAKING_LAG, "s", ">= 0",
          "the attitude's lag to a new tilt, braking: horizontal speed its lag still takes out is not asked twice",
          non_negative),
    Param("braking_settle", BRAKING_SETTLE, "s", ">= 0", "of the braking left, when the ground speed is to be out", non_negative),
    Param("axis_limit", AXIS_LIMIT, "-", ">= 0",
          "largest integral correction of the thrust axis braking under the canopy, horizontal/vertical (0: none)",
          non_negative),
    Param("lag_counts_ceiling", True, "-", "true, false",
          "where the mixer's ceiling binds, the lag term counts the thrust given, not the thrust asked", boolean),
    Param("learn_headroom", True, "-", "true, false",
          "learn the attitude law's share of the collective while braking, and plan the limb on what it leaves",
          boolean),
    Param("brake_in_fitted_air", True, "-", "true, false",
          "the limb's drag from the scale and wind fitted under the chute (false: the scale learnt, still air)",
          boolean),
)

#: Rows of the MPC powered descent (``deorbit-mpc``).
MPC_ROWS: tuple[Param, ...] = (
    Param("handover_fraction", 0.5, "-", "(0, 1)",
          "the MPC takes over where the descent law's braking curve at this fraction of the net thrust is reached",
          fraction_open),
    Param("horizon_steps", 20, "-", "integer >= 2", "prediction steps of each period's programme", integer_at_least(2)),
    Param("min_time_to_go", MIN_TIME_TO_GO, "s", "> 0", "shortest horizon, once the reference's end is (nearly) passed", positive),
    Param("max_tilt", MAX_TILT, "rad", "(0, pi/2]", "tilt limit of the thrust in the programme", at_most(PI_2, "pi/2 rad")),
    Param("glide_slope", 0.0, "rad", "[0, pi/2)", "glide-slope constraint (0: none; the hover has no landing spot)",
          angle_in(0.0, PI_2, "[0, pi/2)")),
    Param("reference_steps", 20, "-", "integer >= 10", "nodes of the minimum-fuel reference", integer_at_least(10)),
    Param("reference_thrust", 0.94, "-", "(0, 1]",
          "fraction of the thrust the reference is solved at: it fixes the end time", fraction),
    Param("attitude_lag", ATTITUDE_LAG, "s", ">= 0",
          "how late the programme expects the thrust axis to follow its command (the attitude loop's mean delay)",
          optional(non_negative)),
    Param("plan_reserve", 0.04, "-", "[0, 1)",
          "share of the programme's thrust bound its plan keeps in hand from 1 s ahead on", share),
    Param("target_above", 1.5, "m", "[0, hover_band)",
          "the programme plans to rest this far over the demand: a plan that falls behind stops in the band",
          non_negative),
    Param("limb_time", 1.0, "s", ">= 0",
          "in its last this-long the vertical thrust is bounded by the constant deceleration to rest (0: never)",
          non_negative),
    Param("coast_collective", COAST_COLLECTIVE, "-", "[0, 1)",
          "before its braking, while the programme asks for less collective, coast along the airflow (0: never)",
          share),
    Param("axis_time", AXIS_TIME, "s", "> 0", "integral time of the braking's correction of the thrust axis", positive),
    Param("axis_limit", AXIS_LIMIT, "-", ">= 0",
          "largest integral correction of the thrust axis braking under the canopy, horizontal/vertical (0: none)",
          non_negative),
    Param("stop_within_period", True, "-", "true, false",
          "braking, cap the thrust at what stops the fall within one control period", boolean),
)

DEORBIT_PARAMS = ParamTable(MISSION_ROWS + SCHEDULED_ROWS)
DEORBIT_MPC_PARAMS = ParamTable(MISSION_ROWS + MPC_ROWS)
