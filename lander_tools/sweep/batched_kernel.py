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

A flight that touches down stops with the state before and after that step: the caller hands them
to the Simulation's own touchdown code (interpolation, classification). Flights are independent,
so the ``prange`` over them gives the same numbers whatever the thread count.
"""
from __future__ import annotations

import math

import numpy as np

import lander_autopilot.controllers.compiled as _law
import lander_sim.fast.lander_kernel as _kernel
from lander_autopilot.controllers.compiled import D_ALT, law_update
from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import HAVE_NUMBA, P_EULER, P_PIVOT, verlet_step, verlet_step_quaternion
from lander_sim.physics.constants import MARS_RADIUS

# The compiled loop calls the law and the Verlet step of those modules: recompile when they change.
invalidate_if_changed(__file__, _law.__file__, _kernel.__file__)

try:
    from numba import njit, prange
except ImportError:  # pragma: no cover - numba is a requirement of this path
    njit = None  # type: ignore[assignment]  # no compiled path: the plain-Python loops below run
    prange = range  # type: ignore[misc]

__all__ = ["HAVE_NUMBA", "TERM_DIVERGED", "TERM_ERROR", "TERM_OK", "TERM_TOUCHDOWN", "fly_flights"]

#: A physics step no flight reaches (no failure pending).
_NEVER = 1 << 62

#: How a flight of the kernel ended.
TERM_OK, TERM_TOUCHDOWN, TERM_DIVERGED, TERM_ERROR = 0, 1, 2, 3


def _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
             law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
             err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states):  # pragma: no cover - compiled
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
    fuel_out = False
    quaternion = kp[P_EULER] == 0.0 and kp[P_PIVOT] == 0.0
    next_fail = 0  # the first physics step at which a thruster failure may be due
    flying = True
    kstep = 0
    draw = 0
    term = TERM_OK
    sat_count = 0
    ns = 0
    for k in range(n_ctrl + 1):
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
    n_samples[f] = ns
    sats[f] = sat_count
    fuel[f, 1] = y[13]
    terminal[f] = term


def _fly_all(y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
             law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
             err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states):  # pragma: no cover - compiled
    for f in prange(y0.shape[0]):
        _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                 law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                 err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states)


def _fly_all_in_order(y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                      law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                      err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before,
                      states):  # pragma: no cover - compiled
    """:func:`_fly_all` on one thread. A function of its own: numba's on-disk cache keys an entry by
    the function and its signature, not by ``parallel``, so one function compiled both ways would
    share one entry, and the serial path could load the threaded code (whose OpenMP layer then
    forbids the worker processes the sweep forks)."""
    for f in range(y0.shape[0]):
        _fly_one(f, y0, kparams, force, torque, burn, mean_wind, gust_ab, gust_g0, gust_w, fail_step, fail_thruster,
                 law, K, d_before, d_after, t_change, n_ctrl, n_sub, period, dt, stop_radius,
                 err, tilt, rate, n_samples, sats, fuel, terminal, y_last, y_prev_last, k_last, v_before, states)


if njit is not None:
    _fly_one = njit(cache=True)(_fly_one)
    _fly_all_parallel = njit(cache=True, parallel=True)(_fly_all)
    _fly_all_serial = njit(cache=True)(_fly_all_in_order)
else:  # pragma: no cover - numba absent
    _fly_all_parallel, _fly_all_serial = _fly_all, _fly_all_in_order  # type: ignore[unreachable]


def fly_flights(inputs: dict[str, np.ndarray], law: np.ndarray, K: np.ndarray, n_ctrl: int, n_sub: int, period: float, dt: float,
                stop_radius: float, parallel: bool = True, record_states: bool = False) -> dict[str, np.ndarray]:
    """Fly every flight of ``inputs`` (arrays over flights, see :mod:`lander_tools.sweep.batched`).

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
       out["terminal"], out["y_last"], out["y_prev_last"], out["k_last"], out["v_before"], out["states"])
    return out
