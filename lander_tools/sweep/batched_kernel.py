"""Compiled closed loop: state -> linear law -> throttles -> Verlet steps, for many flights at once.

One flight of :func:`fly_flights` is, step for step, the core-only loop of
:func:`lander_tools.sweep.flight.fly_case` flown by :class:`~lander_sim.simulation.Simulation` on
its compiled fast path: every control period the law (:func:`~lander_autopilot.controllers.compiled.law_update`,
the compiled form of the Python law) reads the state, its throttles are held over ``n_sub``
velocity-Verlet steps (:func:`lander_sim.fast.lander_kernel.verlet_step`), and per physics step
the due thruster failures take effect, the wind is the mean plus the current Gauss-Markov gust
(``g <- a g + b w``, :mod:`lander_sim.physics.wind`, with the flight's pre-drawn normals ``w``),
and touchdown and fuel-out are checked as ``Simulation._after_step`` does. The samples at the
control instants are those of :class:`~lander_tools.sweep.metrics.Samples` (altitude error, tilt,
body rate), so the metrics are computed by the same :func:`~lander_tools.sweep.metrics.evaluate`.

On the estimate (``navigation``), a flight's sensors and navigation filter ride along as
:class:`~lander_autopilot.estimation.onboard.Onboard` carries them on the per-flight path: at the
first instant the sensors due sample the truth and the filter takes their readings; after every
physics step still flying the sensors due sample the step (:func:`lander_sim.sensors.compiled.sample_step`
on :func:`~lander_sim.sensors.compiled.truth_after_step`) and the filter propagates on the IMU
reading, over the difference of the readings' nanosecond stamps, then takes the other readings in
table order (:mod:`lander_autopilot.estimation.compiled`); at a control instant the law is given the
estimate (position, velocity, attitude, ``omega_m - b_g``) and the true fuel.

A flight that touches down stops with the state before and after that step: the caller hands them
to the Simulation's own touchdown code (interpolation, classification). Flights are independent,
so the ``prange`` over them gives the same numbers whatever the thread count.
"""
from __future__ import annotations

import math

import numpy as np

import lander_autopilot.controllers.compiled as _law
import lander_autopilot.estimation.compiled as _filter
import lander_sim.fast.lander_kernel as _kernel
import lander_sim.fast.quaternion as _quaternion
import lander_sim.sensors.compiled as _sensors
from lander_autopilot.controllers.compiled import D_ALT, law_update
from lander_autopilot.estimation.compiled import (
    N_ERR,
    N_X,
    nav_propagate,
    nav_update_altimeter,
    nav_update_doppler,
    nav_update_ground_fix,
    nav_update_star_tracker,
)
from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import HAVE_NUMBA, P_EULER, P_PIVOT, verlet_step, verlet_step_quaternion
from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.sensors.compiled import ALT as S_ALT
from lander_sim.sensors.compiled import DOP as S_DOP
from lander_sim.sensors.compiled import FIX as S_FIX
from lander_sim.sensors.compiled import IMU as S_IMU
from lander_sim.sensors.compiled import N_SENSORS, N_SP, SP_ALT_BEAM, SP_GM, SP_RADIUS, sample_step, truth_after_step
from lander_sim.sensors.compiled import STAR as S_STAR

# The compiled loop calls the law, the Verlet step, the sensors and the filter of those modules
# (and, through the last two, the quaternion kernels): recompile when they change.
invalidate_if_changed(__file__, _law.__file__, _kernel.__file__, _filter.__file__, _sensors.__file__,
                      _quaternion.__file__)

try:
    from numba import njit, prange
except ImportError:  # pragma: no cover - numba is a requirement of this path
    njit = None  # type: ignore[assignment]  # no compiled path: the plain-Python loops below run
    prange = range  # type: ignore[misc]

__all__ = ["HAVE_NUMBA", "NAV_KEYS", "TERM_DIVERGED", "TERM_ERROR", "TERM_OK", "TERM_TOUCHDOWN", "fly_flights", "no_nav"]

#: A physics step no flight reaches (no failure pending).
_NEVER = 1 << 62

#: How a flight of the kernel ended.
TERM_OK, TERM_TOUCHDOWN, TERM_DIVERGED, TERM_ERROR = 0, 1, 2, 3


def _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
             law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
             err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states,
             nav):  # pragma: no cover - compiled
    n = force.shape[1]
    y = y0[f].copy()
    y_prev = y.copy()
    a0 = np.empty(6)
    a1 = np.empty(6)
    est = np.empty(14)
    e = np.empty(6)
    u = np.empty(n)
    thr = np.zeros(n)
    failed = np.zeros(n, dtype=np.bool_)
    wind = np.empty(3)
    law_state = np.zeros(3)
    g = np.empty(3)
    for j in range(3):
        g[j] = gust_g0[f, j]  # the process's stationary start
    fuel[f, 0] = y[13]
    kp, fo, to, bu = kparams[f], force[f], torque[f], burn[f]  # views hoisted out of the loop
    db, da = d_before[f], d_after[f]
    term = TERM_OK
    fuel_out = False
    quaternion = kp[P_EULER] == 0.0 and kp[P_PIVOT] == 0.0
    # On the estimate (nav's arrays have a row per flight): the sensors and the filter ride along.
    on_nav = nav[0].shape[0] > 0
    sp, sbias, wn, off, xs, P, qc, cur, nxt, last, zs, sg, got, om, fb, omega_m, ye, imu_ns = _nav_start(f, nav, on_nav)
    if on_nav:  # the flight's first instant: the sensors due at t = 0 (the IMU's body rate is the state's)
        for j in range(3):
            om[j] = y[10 + j]
        if not sample_step(0.0, y, om, fb, sp, sbias, wn, off, cur, nxt, last, zs, sg, got):
            term = TERM_ERROR
        imu_ns = _nav_feed(0, got, zs, sg, xs, P, sp, qc, imu_ns, omega_m)
    next_fail = 0  # the first physics step at which a thruster failure may be due
    flying = True
    kstep = 0
    draw = 0
    sat_count = 0
    ns = 0
    for k in range(n_ctrl + 1):
        if term == TERM_ERROR:  # the sensors ran out of packed normals: the per-flight path flies it
            break
        t = k * period
        finite = True
        for j in range(3):
            if not (math.isfinite(y[j]) and math.isfinite(y[10 + j])):
                finite = False
        if not finite:
            term = TERM_DIVERGED
            break
        dem = da if t >= t_change[f] else db
        # metrics.altitude_and_tilt: body z in the world frame is row 2 of R(q) (eq 13).
        s, a, b, c = y[6], y[7], y[8], y[9]
        rn = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
        up_r = 2.0 * (s * b + a * c) * y[0] + 2.0 * (b * c - s * a) * y[1] + (s * s - a * a - b * b + c * c) * y[2]
        err[f, k] = (rn - MARS_RADIUS) - dem[D_ALT]
        tilt[f, k] = math.acos(max(-1.0, min(1.0, up_r / rn)))
        rate[f, k] = math.sqrt(y[10] * y[10] + y[11] * y[11] + y[12] * y[12])
        ns = k + 1
        if states.shape[1] > 0:
            for j in range(14):
                states[f, k, j] = y[j]
        if not flying:
            term = TERM_TOUCHDOWN
            break
        if k == n_ctrl:
            break
        if on_nav:  # the law reads the estimate (onboard.Onboard.state): the filter's, the fuel the truth's
            for j in range(10):
                ye[j] = xs[j]
            for j in range(3):
                ye[10 + j] = omega_m[j] - xs[10 + j]
            ye[13] = y[13]
            saturated = law_update(law, K, law_state, t, ye, dem, u, e)
        else:
            saturated = law_update(law, K, law_state, t, y, dem, u, e)
        bad = False
        for i in range(n):
            if not (u[i] >= 0.0 and u[i] <= 1.0):
                bad = True
        if bad:  # Simulation.set_throttles would refuse it: the per-flight path reports the error
            term = TERM_ERROR
            break
        sat_count += saturated
        if not fuel_out:
            for i in range(n):
                thr[i] = 0.0 if failed[i] else u[i]
        for j in range(3):
            v_before[f, j] = y[3 + j]
        for sub in range(n_sub):
            if not flying:
                kstep += n_sub - sub
                break
            if kstep >= next_fail:  # a failure may be due: take the due ones, find the next
                next_fail = _NEVER
                for q in range(fail_step.shape[1]):
                    if fail_step[f, q] >= 0 and fail_step[f, q] <= kstep and not failed[fail_thruster[f, q]]:
                        failed[fail_thruster[f, q]] = True
                        thr[fail_thruster[f, q]] = 0.0
                    if fail_step[f, q] > kstep and not failed[fail_thruster[f, q]]:
                        next_fail = min(next_fail, fail_step[f, q])
            for j in range(3):
                wind[j] = mean_wind[f, j] + g[j]
            for j in range(14):
                y_prev[j] = y[j]
            if quaternion:  # the free quaternion lander's scalar step, inlined here
                verlet_step_quaternion(y, dt, kp, fo, to, bu, thr, wind)
            else:
                verlet_step(y, dt, kp, fo, to, bu, thr, wind, a0, a1, est)
            kstep += 1
            if gust_ab[f, 0] != 0.0:
                for j in range(3):
                    g[j] = g[j] * gust_ab[f, 1] + gust_w[f, draw, j] * gust_ab[f, 2]
                draw += 1
            if stop_radius > 0.0 and y[0] * y[0] + y[1] * y[1] + y[2] * y[2] < stop_radius * stop_radius:
                flying = False
                for j in range(14):
                    y_last[f, j] = y[j]
                    y_prev_last[f, j] = y_prev[j]
                k_last[f] = kstep
                for i in range(n):
                    thr[i] = 0.0
                continue
            if not fuel_out and n > 0 and y[13] <= 0.0:
                fuel_out = True
                for i in range(n):
                    thr[i] = 0.0
            if on_nav:  # the sensors sample the step, the filter takes their readings (onboard.Onboard.step)
                ts = kstep * dt
                truth_after_step(y_prev, y, ts - (kstep - 1) * dt, sp[SP_GM], om, fb)
                if not sample_step(ts, y, om, fb, sp, sbias, wn, off, cur, nxt, last, zs, sg, got):
                    term = TERM_ERROR
                    break
                imu_ns = _nav_feed(_stamp_ns(ts), got, zs, sg, xs, P, sp, qc, imu_ns, omega_m)
    n_samples[f] = ns
    sats[f] = sat_count
    fuel[f, 1] = y[13]
    terminal[f] = term


def _stamp_ns(t):  # pragma: no cover - compiled
    """``int(round(t 1e9))``: a reading's stamp [ns], as ``onboard.stamp_ns`` (rounded half to even)."""
    return np.int64(np.rint(t * 1e9))


def _nav_start(f, nav, on_nav):  # pragma: no cover - compiled
    """Flight ``f``'s sensors and filter at switch-on (``nav``: see :func:`fly_flights`), or empty
    stand-ins of the same types for a flight on the truth."""
    sp_all, bias_all, w_all, off_all, x0_all, P0_all, qc_all = nav
    if on_nav:
        sp, sbias, wn, off = sp_all[f], bias_all[f].copy(), w_all[f], off_all[f]
        xs, P, qc = x0_all[f].copy(), P0_all[f].copy(), qc_all[f]
    else:
        sp, sbias, wn, off = np.zeros(N_SP), np.zeros(6), np.zeros(0), np.zeros(N_SENSORS + 1, dtype=np.int64)
        xs, P, qc = np.zeros(N_X), np.zeros((N_ERR, N_ERR)), np.zeros(12)
    cur = off[0:N_SENSORS].copy()
    nxt = np.zeros(N_SENSORS)
    last = np.full(N_SENSORS, -1.0)
    zs = np.zeros((N_SENSORS, 7))
    sg = np.zeros((N_SENSORS, 6))
    got = np.zeros(N_SENSORS, dtype=np.int64)
    return (sp, sbias, wn, off, xs, P, qc, cur, nxt, last, zs, sg, got, np.zeros(3), np.zeros(3), np.zeros(3),
            np.zeros(14), np.int64(-1))


def _nav_feed(t_ns, got, zs, sg, xs, P, sp, qc, imu_ns, omega_m):  # pragma: no cover - compiled
    """One step's readings into the filter, in :class:`~lander_autopilot.estimation.ticks.TickFeeder`'s
    order: propagate on the IMU reading (none on the first: it only starts the clock), then each
    aiding sensor's measurement in table order; a refused input leaves the filter as it was.
    Returns the stamp [ns] of the last IMU reading applied (``omega_m`` its gyro reading)."""
    if got[S_IMU] == 1:
        ok = True
        if imu_ns >= 0:
            ok = nav_propagate(xs, P, zs[S_IMU, 0:3], zs[S_IMU, 3:6], (t_ns - imu_ns) * 1e-9, sp[SP_GM], qc)
        if ok:
            imu_ns = t_ns
            for j in range(3):
                omega_m[j] = zs[S_IMU, j]
    if got[S_STAR] == 1:
        nav_update_star_tracker(xs, P, zs[S_STAR, 0:4], sg[S_STAR, 0:3])
    if got[S_ALT] == 1:
        nav_update_altimeter(xs, P, zs[S_ALT, 0], sg[S_ALT, 0], sp[SP_ALT_BEAM:SP_ALT_BEAM + 3], sp[SP_RADIUS])
    if got[S_DOP] == 1:
        nav_update_doppler(xs, P, zs[S_DOP, 0:3], sg[S_DOP, 0:3])
    if got[S_FIX] == 1:
        nav_update_ground_fix(xs, P, zs[S_FIX, 0:6], sg[S_FIX, 0:6])
    return imu_ns


def _fly_all(y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
             law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
             err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states,
             nav):  # pragma: no cover - compiled
    for f in prange(y0.shape[0]):
        _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                 law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                 err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states, nav)


def _fly_all_in_order(y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                      law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                      err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before,
                      states, nav):  # pragma: no cover - compiled
    """:func:`_fly_all` on one thread. A function of its own: numba's on-disk cache keys an entry by
    the function and its signature, not by ``parallel``, so one function compiled both ways would
    share one entry, and the serial path could load the threaded code (whose OpenMP layer then
    forbids the worker processes the sweep forks)."""
    for f in range(y0.shape[0]):
        _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                 law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                 err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states, nav)


if njit is not None:
    _stamp_ns = njit(cache=True)(_stamp_ns)
    _nav_start = njit(cache=True)(_nav_start)
    _nav_feed = njit(cache=True)(_nav_feed)
    _fly_one = njit(cache=True)(_fly_one)
    _fly_all_parallel = njit(cache=True, parallel=True)(_fly_all)
    _fly_all_serial = njit(cache=True)(_fly_all_in_order)
else:  # pragma: no cover - numba absent
    _fly_all_parallel, _fly_all_serial = _fly_all, _fly_all_in_order  # type: ignore[unreachable]


#: The ``nav`` arrays of :func:`fly_flights`, in order.
NAV_KEYS = ("nav_sp", "nav_bias", "nav_w", "nav_off", "nav_x0", "nav_P0", "nav_qc")


def no_nav() -> tuple[np.ndarray, ...]:
    """``nav`` for flights on the truth: no rows."""
    return (np.zeros((0, N_SP)), np.zeros((0, 6)), np.zeros((0, 0)), np.zeros((0, N_SENSORS + 1), dtype=np.int64),
            np.zeros((0, N_X)), np.zeros((0, N_ERR, N_ERR)), np.zeros((0, 12)))


def fly_flights(inputs: dict[str, np.ndarray], law: np.ndarray, K: np.ndarray, n_ctrl: int, n_sub: int, period: float, dt: float,
                stop_radius: float, parallel: bool = True, record_states: bool = False,
                navigation: bool = False) -> dict[str, np.ndarray]:
    """Fly every flight of ``inputs`` (arrays over flights, see :mod:`lander_tools.sweep.batched`).

    ``navigation``: the law flies on the estimate, from the sensors and the filter of the
    ``inputs``' :data:`NAV_KEYS` arrays (a row per flight: the packed sensors
    (:func:`lander_sim.sensors.compiled.pack_suite`), the filter's start ``x`` and ``P``
    (:mod:`lander_autopilot.estimation.compiled`) and its noise densities squared).

    Returns arrays over flights: ``err``/``tilt``/``rate`` (F, n_ctrl + 1) of which the first
    ``n_samples`` are flown, ``sats`` (saturated updates), ``fuel`` (start, end) [kg],
    ``terminal`` (``TERM_*``) and, for touchdowns, ``y_last``/``y_prev_last``/``k_last`` (state
    after and before the touchdown step, steps taken) and ``v_before`` (velocity at the start of
    the last control period, world frame [m/s]); with ``record_states`` also ``states``
    (F, n_ctrl + 1, 14), the flat state at each control instant flown.
    """
    F = inputs["y0"].shape[0]
    out = {
        "err": np.zeros((F, n_ctrl + 1)), "tilt": np.zeros((F, n_ctrl + 1)), "rate": np.zeros((F, n_ctrl + 1)),
        "n_samples": np.zeros(F, dtype=np.int64), "sats": np.zeros(F, dtype=np.int64), "fuel": np.zeros((F, 2)),
        "terminal": np.zeros(F, dtype=np.int64), "y_last": np.zeros((F, 14)), "y_prev_last": np.zeros((F, 14)),
        "k_last": np.zeros(F, dtype=np.int64), "v_before": np.zeros((F, 3)),
        "states": np.zeros((F, n_ctrl + 1 if record_states else 0, 14)),
    }
    fn = _fly_all_parallel if parallel else _fly_all_serial
    fn(inputs["y0"], inputs["kparams"], inputs["force"], inputs["torque"], inputs["burn"], inputs["mean_wind"],
       inputs["gust_ab"], inputs["gust_g0"], inputs["gust_w"], inputs["fail_step"], inputs["fail_thruster"], law, K,
       inputs["d_before"], inputs["d_after"], inputs["t_change"], int(n_ctrl), int(n_sub), float(period), float(dt),
       float(stop_radius), out["err"], out["tilt"], out["rate"], out["n_samples"], out["sats"], out["fuel"],
       out["terminal"], out["y_last"], out["y_prev_last"], out["k_last"], out["v_before"], out["states"],
       tuple(inputs[k] for k in NAV_KEYS) if navigation else no_nav())
    return out
