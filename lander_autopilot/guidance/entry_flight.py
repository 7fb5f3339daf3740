"""The drag-only point-mass entry, flown fast: the kernel behind :func:`.deorbit.fly_entry`.

Inverse-square gravity and the body's quadratic drag in the exponential atmosphere, no thrust,
chute packed; world frame ``mars`` (planet-centred, inertial), SI units. The de-orbit law asks this
question once a second of flight through the whole entry (about 1,800 times a flight), so it is
scalar code with no allocation, compiled by numba when available (the same function runs as plain
Python without it).

Integrator: classical RK4 (fourth order) with a step chosen from the state: at most
``max_step`` (5 s), at most ``scale`` of the time to cross a tenth of a scale height vertically
(``0.1 H / |v_r|``), at most ``scale`` of the time the drag takes to change the speed by 5 %
(``0.05 v / a_drag``). The events (chute may open, ground, climbing again) are located by secant
iteration on the event function, each trial point re-integrated by one RK4 step from the last
accepted state, so the located instant carries the method's error, not an interpolation's.
``step_scale`` scales every limit: halving it must shrink the error about 16 times (the test
checks it, and the scipy RK45 solution at rtol 1e-9 against it).
"""
from __future__ import annotations

import math

from lander_sim.fast.lander_kernel import njit  # type: ignore[attr-defined]  # numba's, or the no-numba stand-in

#: outcome codes of :func:`entry_flight`
REACHED_CHUTE, REACHED_GROUND, SKIPPED, NO_ENTRY, TIMED_OUT = 0, 1, 2, 3, 4
#: the event of reaching the top of the atmosphere from above (located, never returned)
_AT_TOP = 5

#: [s] step of the coast above the atmosphere: 0.008 rad of a 2 h orbit, RK4's error is metres
#: after half an orbit
COAST_STEP = 10.0
#: [s] longest step inside the atmosphere
MAX_STEP = 5.0
#: [-] inside the atmosphere a step moves at most this share of a scale height vertically ...
HEIGHT_STEP = 0.1
#: [-] ... and changes the speed by at most this share under drag
SPEED_STEP = 0.05
#: an event is located when its function is within this of its bracket's values (relative), or
#: the bracket within this in time [s]: far under the step's own error
EVENT_TOLERANCE = 1e-9


@njit(cache=True)
def _deriv(x: float, y: float, z: float, vx: float, vy: float, vz: float, gm: float, radius: float,
           kd: float, rho0: float, inv_h: float, top: float) -> tuple[float, float, float]:
    r2 = x * x + y * y + z * z
    r = math.sqrt(r2)
    g = -gm / (r2 * r)
    h = r - radius
    drag = 0.0
    if h <= top:
        drag = kd * rho0 * math.exp(-h * inv_h) * math.sqrt(vx * vx + vy * vy + vz * vz)
    return g * x - drag * vx, g * y - drag * vy, g * z - drag * vz


@njit(cache=True)
def _rk4(s: tuple[float, float, float, float, float, float], dt: float, gm: float, radius: float, kd: float,
         rho0: float, inv_h: float, top: float) -> tuple[float, float, float, float, float, float]:
    x, y, z, vx, vy, vz = s
    a1x, a1y, a1z = _deriv(x, y, z, vx, vy, vz, gm, radius, kd, rho0, inv_h, top)
    h2 = 0.5 * dt
    x2, y2, z2 = x + h2 * vx, y + h2 * vy, z + h2 * vz
    v2x, v2y, v2z = vx + h2 * a1x, vy + h2 * a1y, vz + h2 * a1z
    a2x, a2y, a2z = _deriv(x2, y2, z2, v2x, v2y, v2z, gm, radius, kd, rho0, inv_h, top)
    x3, y3, z3 = x + h2 * v2x, y + h2 * v2y, z + h2 * v2z
    v3x, v3y, v3z = vx + h2 * a2x, vy + h2 * a2y, vz + h2 * a2z
    a3x, a3y, a3z = _deriv(x3, y3, z3, v3x, v3y, v3z, gm, radius, kd, rho0, inv_h, top)
    x4, y4, z4 = x + dt * v3x, y + dt * v3y, z + dt * v3z
    v4x, v4y, v4z = vx + dt * a3x, vy + dt * a3y, vz + dt * a3z
    a4x, a4y, a4z = _deriv(x4, y4, z4, v4x, v4y, v4z, gm, radius, kd, rho0, inv_h, top)
    s6 = dt / 6.0
    return (x + s6 * (vx + 2.0 * v2x + 2.0 * v3x + v4x), y + s6 * (vy + 2.0 * v2y + 2.0 * v3y + v4y),
            z + s6 * (vz + 2.0 * v2z + 2.0 * v3z + v4z), vx + s6 * (a1x + 2.0 * a2x + 2.0 * a3x + a4x),
            vy + s6 * (a1y + 2.0 * a2y + 2.0 * a3y + a4y), vz + s6 * (a1z + 2.0 * a2z + 2.0 * a3z + a4z))


@njit(cache=True)
def _events(s: tuple[float, float, float, float, float, float], radius: float, kc: float, rho0: float,
            inv_h: float, top: float, vmax: float, dmax: float) -> tuple[float, float, float]:
    """(chute may not open yet: > 0, altitude, radial speed x |r|)."""
    x, y, z, vx, vy, vz = s
    h = math.sqrt(x * x + y * y + z * z) - radius
    v2 = vx * vx + vy * vy + vz * vz
    chute = 1.0
    if h <= top:
        chute = max(math.sqrt(v2) - vmax, kc * rho0 * math.exp(-h * inv_h) * v2 - dmax)
    return chute, h, x * vx + y * vy + z * vz


@njit(cache=True)
def _event_value(s: tuple[float, float, float, float, float, float], ev: int, radius: float, kc: float,
                 rho0: float, inv_h: float, top: float, vmax: float, dmax: float) -> float:
    """Event function of ``ev``, positive before it fires: chute may not open yet, altitude, minus
    the radial speed (climbing again), altitude above the top of the atmosphere."""
    chute, h, rv = _events(s, radius, kc, rho0, inv_h, top, vmax, dmax)
    if ev == REACHED_CHUTE:
        return chute
    if ev == REACHED_GROUND:
        return h
    if ev == SKIPPED:
        return -rv
    return h - top


@njit(cache=True)
def _locate(s: tuple[float, float, float, float, float, float], dt: float, ev: int, f0: float, f1: float,
            gm: float, radius: float, kd: float, kc: float, rho0: float, inv_h: float, top: float, vmax: float,
            dmax: float) -> tuple[float, tuple[float, float, float, float, float, float]]:
    """``(t, state)`` where event ``ev`` fires within the step ``dt`` from ``s`` (``f0 > 0 >= f1``):
    regula falsi with the Illinois modification on the event function, each trial point one RK4
    step from ``s``, to 1e-9 of the bracket's values or 1e-9 s."""
    lo, hi, f_lo, f_hi = 0.0, dt, f0, f1
    tm, sm = dt, _rk4(s, dt, gm, radius, kd, rho0, inv_h, top)
    side = 0
    for _ in range(60):
        tm = lo - f_lo * (hi - lo) / (f_hi - f_lo)
        sm = _rk4(s, tm, gm, radius, kd, rho0, inv_h, top)
        fm = _event_value(sm, ev, radius, kc, rho0, inv_h, top, vmax, dmax)
        if abs(fm) <= EVENT_TOLERANCE * (abs(f0) + abs(f1)) or hi - lo < EVENT_TOLERANCE:
            break
        if fm > 0.0:
            lo, f_lo = tm, fm
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi, f_hi = tm, fm
            if side == -1:
                f_lo *= 0.5
            side = -1
    return tm, sm


@njit(cache=True)
def _step_size(s: tuple[float, float, float, float, float, float], radius: float, kd: float, rho0: float,
               inv_h: float, top: float, scale: float, max_step: float, coast_step: float) -> float:
    x, y, z, vx, vy, vz = s
    r = math.sqrt(x * x + y * y + z * z)
    h = r - radius
    if h > top:
        return coast_step * scale
    v = math.sqrt(vx * vx + vy * vy + vz * vz)
    vr = abs(x * vx + y * vy + z * vz) / r
    dt = max_step
    if vr > 0.0:
        dt = min(dt, HEIGHT_STEP / (inv_h * vr))
    a_drag = kd * rho0 * math.exp(-h * inv_h) * v * v
    if a_drag > 0.0:
        dt = min(dt, SPEED_STEP * v / a_drag)
    return dt * scale


@njit(cache=True)
def entry_flight(x: float, y: float, z: float, vx: float, vy: float, vz: float, gm: float, radius: float,
                 kd: float, kc: float, rho0: float, scale_height: float, top: float, vmax: float, dmax: float,
                 coast_max: float, t_max: float, step_scale: float
                 ) -> tuple[int, float, float, float, float, float, float, float]:
    """Fly from the state (world frame, m and m/s) until the first event; see the module docstring.

    ``kd`` = 1/2 Cd A / m of the body [m^2/kg], ``kc`` = 1/2 Cd A of the canopy [m^2], ``rho0`` and
    ``scale_height`` the atmosphere, ``top`` its exosphere altitude, ``vmax`` [m/s] and ``dmax`` [N]
    the chute's limits, ``coast_max`` [s] the longest coast to the top of the atmosphere tried,
    ``t_max`` [s] the longest flight inside it.

    Returns ``(outcome, chute_speed, chute_altitude, peak_drag_deceleration, entry_speed,
    entry_flight_path_angle, t, altitude)``: the outcome code (module constants), the speed [m/s]
    and altitude [m] where the chute may first open (nan unless REACHED_CHUTE), the largest drag
    deceleration [m/s^2] seen at the step points, the speed [m/s] and flight path angle below the
    horizontal [rad] at the top of the atmosphere (or at the start, if inside), the event's time [s]
    and altitude [m].
    """
    inv_h = 1.0 / scale_height
    s = (x, y, z, vx, vy, vz)
    t = 0.0
    nan = math.nan
    # the coast above the atmosphere: two-body, to the top (steps of COAST_STEP)
    coast_step = COAST_STEP
    chute, h, rv = _events(s, radius, kc, rho0, inv_h, top, vmax, dmax)
    while h > top:
        if t >= coast_max:
            return NO_ENTRY, nan, nan, 0.0, nan, nan, t, h
        dt = coast_step * step_scale
        s1 = _rk4(s, dt, gm, radius, 0.0, rho0, inv_h, top)
        _, h1, _ = _events(s1, radius, kc, rho0, inv_h, top, vmax, dmax)
        if h1 <= top:
            tm, s = _locate(s, dt, _AT_TOP, h - top, h1 - top, gm, radius, 0.0, kc, rho0, inv_h, top, vmax, dmax)
            t += tm
            break
        s, t, h = s1, t + dt, h1
    x, y, z, vx, vy, vz = s
    r = math.sqrt(x * x + y * y + z * z)
    v_entry = math.sqrt(vx * vx + vy * vy + vz * vz)
    gamma = -math.asin(max(-1.0, min(1.0, (x * vx + y * vy + z * vz) / (r * v_entry))))
    chute, h, rv = _events(s, radius, kc, rho0, inv_h, top, vmax, dmax)
    peak = kd * rho0 * math.exp(-h * inv_h) * v_entry * v_entry if h <= top else 0.0
    t_entry = t
    while t - t_entry < t_max:
        dt = _step_size(s, radius, kd, rho0, inv_h, top, step_scale, MAX_STEP, coast_step)
        s1 = _rk4(s, dt, gm, radius, kd, rho0, inv_h, top)
        chute1, h1, rv1 = _events(s1, radius, kc, rho0, inv_h, top, vmax, dmax)
        # which event fires first in this step (chute: + to -; ground: h to <= 0; climbing: - to +)
        which = -1
        if h1 <= 0.0:
            which = REACHED_GROUND
        if chute > 0.0 and chute1 <= 0.0:
            which = REACHED_CHUTE
        if rv < 0.0 and rv1 >= 0.0:
            which = SKIPPED
        if which < 0:
            v1 = math.sqrt(s1[3] * s1[3] + s1[4] * s1[4] + s1[5] * s1[5])
            if h1 <= top:
                peak = max(peak, kd * rho0 * math.exp(-h1 * inv_h) * v1 * v1)
            s, t, chute, h, rv = s1, t + dt, chute1, h1, rv1
            continue
        # Events may share the step: locate each candidate by secant and keep the earliest. Secant
        # (regula falsi, Illinois) on the event function along RK4 sub-steps from the last state.
        best_t, best_s, best = dt, s1, which
        for ev, f0, f1, fires in ((REACHED_CHUTE, chute, chute1, chute > 0.0 and chute1 <= 0.0),
                                  (REACHED_GROUND, h, h1, h1 <= 0.0), (SKIPPED, -rv, -rv1, rv < 0.0 and rv1 >= 0.0)):
            if fires:
                tm, sm = _locate(s, dt, ev, f0, f1, gm, radius, kd, kc, rho0, inv_h, top, vmax, dmax)
                if tm <= best_t:
                    best_t, best_s, best = tm, sm, ev
        s, t = best_s, t + best_t
        x, y, z, vx, vy, vz = s
        h = math.sqrt(x * x + y * y + z * z) - radius
        v = math.sqrt(vx * vx + vy * vy + vz * vz)
        if h <= top:
            peak = max(peak, kd * rho0 * math.exp(-h * inv_h) * v * v)
        if best == REACHED_CHUTE:
            return REACHED_CHUTE, v, h, peak, v_entry, gamma, t, h
        return best, nan, nan, peak, v_entry, gamma, t, h
    return TIMED_OUT, nan, nan, peak, v_entry, gamma, t, h
