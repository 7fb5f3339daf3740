"""De-orbit planning: the burn that takes the lander from its orbit into an entry it survives.

Plain numpy and scipy (no rclpy). World frame ``mars``: planet-centred, inertial, SI units.

The burn is retrograde (against the velocity) at the orbit's apoapsis, or after ``slew_time`` for an
orbit too close to circular to have one worth waiting for: lowering the periapsis is cheapest there
(vis-viva). "Too close to circular" allows for the navigation error of the state the plan is made
from (:func:`circular_tolerance`): an apoapsis the error alone could make is not waited for. Its
size puts the periapsis at a chosen altitude inside the atmosphere; the altitude is chosen by
flying the entry as a point mass under inverse-square gravity and drag (the lander's sphere, its
models' constants) and keeping the highest periapsis whose entry is captured in one
pass and slows below the parachute's deployment speed with the canopy's drag under its limit: a
higher periapsis costs less fuel (the burn is smaller) and decelerates more gently.

Fuel: rocket equation with the lander's effective exhaust speed ``c = T_axial / m_dot``. The burn is
finite (tens of seconds): it is centred on the apoapsis, which costs a gravity loss of order
``(omega t_burn)^2 / 24`` of the burn, under 0.1 % here, so it is not modelled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import Atmosphere

from .entry_flight import NO_ENTRY, SKIPPED, entry_flight

#: [s] time before the de-orbit burn may start: the attitude manoeuvre that turns the thrust axis
#: retrograde: the mission's attitude law (poles -1/s, time constant 1 s) settles a half-turn well
#: within a minute (the mission's ``slew_time``)
SLEW_TIME = 60.0
#: [m] lowest altitude the plan (and the entry's prediction) lets the chute open at: height for the
#: canopy to brake the fall before the powered descent, three times the lowest the landing law asks
#: for it at (``chute_min_altitude``, 1 km over contact) (the mission's ``chute_altitude``)
CHUTE_ALTITUDE = 3000.0
#: [s] longest entry flown by the planner's prediction, from the top of the atmosphere: two hours,
#: over a low orbit's period (1.8 h at 200 km), so an entry that grazes the atmosphere for a whole
#: revolution is still followed to its end
ENTRY_MAX_TIME = 7200.0
#: [m] an orbit whose apsides differ by under this has no apoapsis worth waiting for: the burn
#: starts after the slew (the speed at the apoapsis differs from the mean by ~v dr / 4a: 0.24 m/s
#: for 1 km at 200 km, against a de-orbit burn of tens of m/s)
CIRCULAR_ORBIT = 1000.0
#: [-] how many standard deviations of the navigation error the circularity test allows for: 3 sigma
#: on every axis at once (a circular orbit seen through a Gaussian error of that sigma is taken for
#: elliptic in about 0.1 % of draws: ``P(4 x^2 + y^2 > 45)`` for unit normals x, y)
NAVIGATION_SIGMAS = 3.0
#: [-] eccentricity under which an orbit is circular for Kepler's equation (no apoapsis defined)
CIRCULAR_ECCENTRICITY = 1e-9
#: Two-body propagation's tolerances: relative 1e-10 and absolute 1e-6 (m, m/s), metres over an
#: orbit, under the planner's ~1 m precision
PROPAGATION_RTOL = 1e-10
PROPAGATION_ATOL = 1e-6
#: [s] slack on the burn's start against the slew's end: a burn planned to start at the slew's end
#: (rounding of ~1e-12 s) is not pushed to the next apoapsis
START_SLACK = 1e-9
#: [m] a kilometre, for messages
KM = 1e3


@dataclass(frozen=True)
class EntryVehicle:
    """What the plan needs of the lander (SI units).

    axial_thrust : total thrust along the body axis with every thruster flat out [N].
    fuel_rate : total fuel flow flat out [kg/s].
    dry_mass : [kg]. drag_area, drag_cd : the body's sphere drag (``F = 1/2 rho Cd A v^2``).
    chute_area, chute_cd, chute_max_speed, chute_max_drag : the parachute and its limits.
    """

    axial_thrust: float
    fuel_rate: float
    dry_mass: float = c.LANDER_DRY_MASS
    drag_area: float = c.SPHERE_DRAG_AREA
    drag_cd: float = c.SPHERE_DRAG_COEFFICIENT
    chute_area: float = math.pi * c.PARACHUTE_RADIUS**2
    chute_cd: float = c.PARACHUTE_DRAG_COEFFICIENT
    chute_max_speed: float = c.PARACHUTE_MAX_SPEED
    chute_max_drag: float = c.PARACHUTE_MAX_DRAG

    @property
    def exhaust_speed(self) -> float:
        """Effective exhaust speed ``c = T / m_dot`` [m/s]."""
        return self.axial_thrust / self.fuel_rate


@dataclass(frozen=True)
class Orbit:
    """Osculating two-body elements of a state (radii in m from the planet's centre)."""

    semi_major_axis: float
    eccentricity: float
    periapsis_radius: float
    apoapsis_radius: float
    time_to_apoapsis: float  # s from the state; 0 for a circular orbit

    @classmethod
    def of(cls, position_W: np.ndarray, velocity_W: np.ndarray, gm: float = c.GM_MARS) -> Orbit:
        r_vec, v_vec = np.asarray(position_W, float), np.asarray(velocity_W, float)
        r, v2 = float(np.linalg.norm(r_vec)), float(v_vec @ v_vec)
        energy = v2 / 2 - gm / r
        if energy >= 0:
            raise ValueError(f"not a closed orbit (specific energy {energy:.1f} J/kg >= 0)")
        a = -gm / (2 * energy)
        e_vec = ((v2 - gm / r) * r_vec - (r_vec @ v_vec) * v_vec) / gm
        e = float(np.linalg.norm(e_vec))
        rp, ra = a * (1 - e), a * (1 + e)
        if e < CIRCULAR_ECCENTRICITY:
            return cls(a, e, rp, ra, 0.0)
        # eccentric anomaly now, then Kepler's equation for the time to E = pi
        cos_E = (1 - r / a) / e
        sin_E = float(r_vec @ v_vec) / (e * math.sqrt(gm * a))
        E = math.atan2(sin_E, cos_E)
        n = math.sqrt(gm / a**3)
        M = E - e * math.sin(E)
        dt = ((math.pi - M) % (2 * math.pi)) / n
        return cls(a, e, rp, ra, dt)


@dataclass(frozen=True)
class EntryCheck:
    """The point-mass entry after the burn, flown to the surface or to chute deployment."""

    captured: bool  # came down in one pass: never climbing between the top of the atmosphere and the chute
    chute_speed: float  # speed when the chute can open (below max speed, drag under its limit) [m/s]
    chute_altitude: float  # altitude of that instant [m]; nan when never
    peak_deceleration: float  # largest drag deceleration [m/s^2]
    entry_speed: float  # speed at the top of the atmosphere [m/s]
    entry_flight_path_angle: float  # below the local horizontal there [rad]

    @property
    def survivable(self) -> bool:
        return self.captured and math.isfinite(self.chute_altitude)


@dataclass(frozen=True)
class DeorbitPlan:
    """The burn and what it leads to. Times in s from the state the plan was made from."""

    burn_start: float
    burn_duration: float
    direction_W: np.ndarray  # unit vector the thrust points along (retrograde) at the burn's centre
    delta_v: float  # m/s
    fuel: float  # kg burnt
    fuel_left: float  # kg after the burn
    periapsis_altitude: float  # m
    entry: EntryCheck


def circular_tolerance(semi_major_axis: float, velocity_sigma: float = 0.0, position_sigma: float = 0.0,
                       sigmas: float = NAVIGATION_SIGMAS, gm: float = c.GM_MARS) -> float:
    """[m] Apsides difference under which an orbit of ``semi_major_axis`` [m] counts as circular, for a
    state known to ``velocity_sigma`` [m/s] and ``position_sigma`` [m] (1 sigma per axis; 0: the truth).

    A circular orbit (radius ``a``, speed ``v = sqrt(GM / a)``) seen with velocity errors ``dv_t``
    (along the track) and ``dv_r`` (radial) and a radial position error ``dr`` has, to first order
    in the errors (the eccentricity vector ``e = ((v^2 - GM/r) r - (r.v) v) / GM`` of
    :meth:`Orbit.of`, linearised about the circle), the components ``2 dv_t / v + dr / a`` and
    ``dv_r / v`` at right angles, so its apsides differ by

        r_a - r_p = 2 a e = 2 a sqrt((2 dv_t / v + dr / a)^2 + (dv_r / v)^2)

    (an along-track position error and the normal components change no eccentricity to first order).
    The tolerance is that split for errors of ``sigmas`` standard deviations on every axis at once,
    with the worst signs, and never under :data:`CIRCULAR_ORBIT` (the split not worth waiting for
    even on the truth):

        tol = max(CIRCULAR_ORBIT, 2 a k sqrt((2 sigma_v / v + sigma_r / a)^2 + (sigma_v / v)^2))

    At 1.2 Mars radii (a = 4074 km, v = 3242 m/s), 0.5 m/s and 10 m at 3 sigma: 8.4 km.
    """
    a = semi_major_axis
    v = math.sqrt(gm / a)
    return max(CIRCULAR_ORBIT, 2 * a * sigmas * math.hypot(2 * velocity_sigma / v + position_sigma / a, velocity_sigma / v))


def _propagate(position_W: np.ndarray, velocity_W: np.ndarray, t: float, gm: float) -> tuple[np.ndarray, np.ndarray]:
    """Two-body state after ``t`` s (RK45 to 1e-10 relative: the planner's precision is ~1 m)."""
    from scipy.integrate import solve_ivp

    if t <= 0:
        return np.array(position_W, float), np.array(velocity_W, float)

    def f(_t: float, y: np.ndarray) -> np.ndarray:
        r = y[:3]
        return np.concatenate([y[3:], -gm * r / np.linalg.norm(r) ** 3])

    sol = solve_ivp(f, (0, t), np.concatenate([position_W, velocity_W]), rtol=PROPAGATION_RTOL, atol=PROPAGATION_ATOL)
    return sol.y[:3, -1], sol.y[3:, -1]


def fly_entry(position_W: np.ndarray, velocity_W: np.ndarray, mass: float, vehicle: EntryVehicle,
              gm: float = c.GM_MARS, radius: float = c.MARS_RADIUS,
              atmosphere: Atmosphere | None = None, step_scale: float = 1.0) -> EntryCheck:
    """Fly a point mass (gravity + the body's drag, no thrust, chute packed) from just after the burn.

    Stops at the first instant the parachute could open within its limits (speed below its maximum
    and its drag below its limit at that speed and density), on the surface, or when the lander
    starts climbing after entering the atmosphere (a skip: not captured in this pass; with this
    dense exponential atmosphere a high periapsis still comes down, but an orbit or more later).
    Coasts to the top of the atmosphere for at most one orbital period, then flies at most 7200 s.
    The integration is :func:`.entry_flight.entry_flight` (compiled RK4, its step scaled by
    ``step_scale``; the module docstring says how the step and the events are chosen).
    """
    atmosphere = atmosphere or Atmosphere()
    r0 = float(np.linalg.norm(position_W))
    period = 0.0
    if r0 - radius > atmosphere.exosphere:
        orbit = Orbit.of(position_W, velocity_W, gm)
        period = 2 * math.pi * math.sqrt(orbit.semi_major_axis**3 / gm)
    (x, y, z), (vx, vy, vz) = (float(a) for a in position_W), (float(a) for a in velocity_W)
    outcome, v_chute, h_chute, peak, v_entry, gamma, _t, _h = entry_flight(
        x, y, z, vx, vy, vz, gm, radius, 0.5 * vehicle.drag_cd * vehicle.drag_area / mass,
        0.5 * vehicle.chute_cd * vehicle.chute_area, atmosphere.surface_density, atmosphere.scale_height,
        atmosphere.exosphere, vehicle.chute_max_speed, vehicle.chute_max_drag, period, ENTRY_MAX_TIME, step_scale)
    if outcome == NO_ENTRY:
        return EntryCheck(False, math.nan, math.nan, 0.0, math.nan, math.nan)
    return EntryCheck(outcome != SKIPPED, v_chute, h_chute, peak, v_entry, gamma)


def plan(position_W: np.ndarray, velocity_W: np.ndarray, mass: float, vehicle: EntryVehicle,
         slew_time: float = SLEW_TIME, periapsis_altitudes: tuple[float, ...] = tuple(range(150_000, 9_999, -5_000)),
         min_chute_altitude: float = CHUTE_ALTITUDE, gm: float = c.GM_MARS, radius: float = c.MARS_RADIUS,
         velocity_sigma: float = 0.0, position_sigma: float = 0.0) -> DeorbitPlan:
    """The cheapest single retrograde burn whose entry is survivable (see the module docstring).

    ``velocity_sigma`` [m/s] and ``position_sigma`` [m]: the navigation error of the state (1 sigma
    per axis; 0, the default: the truth). An orbit whose apsides differ by under
    :func:`circular_tolerance` is flown as circular: the burn starts after the slew.

    ``periapsis_altitudes`` are tried from the highest (least fuel) down; the first whose entry is
    captured with the chute able to open at least ``min_chute_altitude`` above the surface wins.
    The burn starts no earlier than ``slew_time`` (the attitude manoeuvre before it). Raises
    ValueError when no altitude works within the fuel on board.
    """
    position_W, velocity_W = np.asarray(position_W, float), np.asarray(velocity_W, float)
    orbit = Orbit.of(position_W, velocity_W, gm)
    period = 2 * math.pi * math.sqrt(orbit.semi_major_axis**3 / gm)
    # An orbit whose apsides differ by under 1 km, or by under what the navigation error alone makes,
    # has no apoapsis worth waiting for: burn after the slew.
    tolerance = circular_tolerance(orbit.semi_major_axis, velocity_sigma, position_sigma, gm=gm)
    circular = orbit.apoapsis_radius - orbit.periapsis_radius < tolerance
    centre = slew_time if circular else orbit.time_to_apoapsis
    for _ in range(3):
        burn = _cheapest_burn(position_W, velocity_W, mass, vehicle, centre, periapsis_altitudes,
                              min_chute_altitude, gm, radius)
        if burn.burn_start >= slew_time - START_SLACK:
            return burn
        # centred on ``centre`` the burn would start inside the slew: half a burn later on a
        # circular orbit (every point is alike), the next apoapsis otherwise
        centre = slew_time + burn.burn_duration / 2 if circular else centre + period
    return burn


def _cheapest_burn(position_W: np.ndarray, velocity_W: np.ndarray, mass: float, vehicle: EntryVehicle,
                   centre: float, periapsis_altitudes: tuple[float, ...], min_chute_altitude: float,
                   gm: float, radius: float) -> DeorbitPlan:
    r_b, v_b = _propagate(position_W, velocity_W, centre, gm)
    rb, speed = float(np.linalg.norm(r_b)), float(np.linalg.norm(v_b))
    fuel_on_board = mass - vehicle.dry_mass
    for hp in periapsis_altitudes:
        rp = radius + hp
        if rp >= rb:
            continue
        # vis-viva: the speed at rb on the orbit with apsides rb and rp. Retrograde: only the speed
        # changes (exact at an apsis, where the velocity is horizontal).
        v_new = math.sqrt(2 * gm * rp / (rb * (rb + rp)))
        dv = speed - v_new
        fuel = mass * (1 - math.exp(-dv / vehicle.exhaust_speed))
        if dv <= 0 or fuel > fuel_on_board:
            continue
        entry = fly_entry(r_b, v_b * (v_new / speed), mass - fuel, vehicle, gm, radius)
        if entry.survivable and entry.chute_altitude >= min_chute_altitude:
            duration = fuel / vehicle.fuel_rate
            return DeorbitPlan(burn_start=centre - duration / 2, burn_duration=duration, direction_W=-v_b / speed,
                               delta_v=dv, fuel=fuel, fuel_left=fuel_on_board - fuel, periapsis_altitude=hp,
                               entry=entry)
    raise ValueError("no survivable single-burn de-orbit within the fuel on board "
                     f"({fuel_on_board:.1f} kg) for periapsis altitudes {periapsis_altitudes[0] / KM:.0f}-"
                     f"{periapsis_altitudes[-1] / KM:.0f} km")
