"""The sensors of a scene as numba kernels, for compiled loops that fly many flights at once.

The same measurement models as the Python sensors (:mod:`.imu`, :mod:`.star_tracker`,
:mod:`.altimeter`, :mod:`.doppler`, :mod:`.ground_fix`), the same schedule
(:class:`.suite.SampleSchedule`: sensor ``k`` of rate ``f`` due at the first step time
``t >= j / f``) and the same truth over a step (:func:`.truth.truth_after_step`)::

    omega_B = log(q(t - dt)^* x q(t)) / dt
    f_B = R_BW(t - dt) [(v(t) - v(t - dt)) / dt - (g_W(r(t - dt)) + g_W(r(t))) / 2]

The random numbers are not drawn here: :func:`pack_suite` takes a :class:`.suite.SensorSuite`
built from the flight's sensors (its switch-on biases already drawn from each sensor's own
generator) and draws, from each sensor's generator, the standard normals its samples will take,
in the order the Python sensor takes them (IMU per sample: the gyro bias walk (3, when the walk is
on), the accelerometer bias walk (3, likewise), the noise (6); star tracker 3, altimeter 1, Doppler
3, ground fix 6, each drawn on a dropout too, as the Python sensors draw them). A sample reads its
normals at the sensor's cursor, so the measurements are the Python sensors' numbers, to the
rounding of the vector products (``R v`` summed in another order than numpy's).

Packed per flight: ``sp`` (:data:`N_SP`, the ``SP_*`` slots), the walking IMU biases ``bias``
(6: gyro, accelerometer), the normals ``w`` and the start of each sensor's normals ``off``
(6: five starts and the end).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

import lander_sim.fast.quaternion as _quaternion
from lander_sim.fast.cache_guard import invalidate_if_changed
from lander_sim.fast.lander_kernel import njit  # type: ignore[attr-defined]
from lander_sim.fast.quaternion import qmul, rotation_into

from .suite import SENSORS, SensorSuite

# The kernels call the quaternion kernels of that module: recompile when it changes.
invalidate_if_changed(__file__, _quaternion.__file__)

__all__ = ["IMU", "N_SENSORS", "N_SP", "pack_suite", "sample_step", "samples_due", "truth_after_step"]

#: Sensor indices: the order of :data:`.suite.SENSORS` (the seed index and the schedule's order).
IMU, STAR, ALT, DOP, FIX = 0, 1, 2, 3, 4
N_SENSORS = 5
assert list(SENSORS) == ["imu", "star_tracker", "altimeter", "doppler", "ground_fix"]

# Slots of ``sp``: the rates (0 for a sensor off), then each sensor's parameters (SI, as its table).
SP_RATE = 0
SP_G_ND, SP_A_ND, SP_G_WALK, SP_A_WALK = 5, 6, 7, 8
SP_ST_NOISE, SP_ST_MAXRATE, SP_ST_BIAS = 9, 10, 11
SP_ALT_FLOOR, SP_ALT_FRAC, SP_ALT_MAX, SP_ALT_BIAS, SP_ALT_BEAM = 14, 15, 16, 17, 18
SP_DOP_FLOOR, SP_DOP_FRAC, SP_DOP_MAX, SP_DOP_BIAS = 21, 22, 23, 24
SP_FIX_R, SP_FIX_V = 27, 28
SP_RADIUS, SP_GM = 29, 30
N_SP = 31

#: Normals a sample takes (the IMU's walks counted apart: 3 each when on).
_PER_SAMPLE = (6, 3, 1, 3, 6)


def samples_due(rate: float, n_steps: int, dt: float) -> int:
    """Most samples a sensor of ``rate`` [Hz] gives over ``n_steps`` steps of ``dt`` [s] and the
    switch-on instant: one a step at most, else one at each ``j / rate`` (the schedule)."""
    return min(n_steps + 1, int(math.floor(n_steps * dt * rate + 1e-9)) + 2)


def pack_suite(suite: SensorSuite, n_steps: int, dt: float, planet_radius: float, gm: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(sp, bias, w, off)`` of a freshly switched-on ``suite`` (module docstring) for a flight of
    ``n_steps`` steps of ``dt`` [s]; ``planet_radius`` [m] and ``gm`` [m^3/s^2]: the scene's
    inverse-square gravity. Draws from the suite's generators (build a suite for this alone)."""
    sp = np.zeros(N_SP)
    bias = np.zeros(6)
    sp[SP_RADIUS], sp[SP_GM] = planet_radius, gm
    parts: list[np.ndarray] = []
    off = np.zeros(N_SENSORS + 1, dtype=np.int64)
    for k, key in enumerate(SENSORS):
        off[k] = sum(p.size for p in parts)
        s: Any = suite.sensors.get(key)
        if s is None:
            continue
        v = s.values
        sp[SP_RATE + k] = float(s.rate)
        per = _PER_SAMPLE[k]
        if k == IMU:
            sp[SP_G_ND], sp[SP_A_ND] = float(v["gyro_noise_density"]), float(v["accel_noise_density"])
            sp[SP_G_WALK], sp[SP_A_WALK] = s.gyro_bias.walk, s.accel_bias.walk
            bias[0:3], bias[3:6] = s.gyro_bias.value, s.accel_bias.value
            per += 3 * (s.gyro_bias.walk > 0.0) + 3 * (s.accel_bias.walk > 0.0)
        elif k == STAR:
            sp[SP_ST_NOISE], sp[SP_ST_MAXRATE] = float(v["noise"]), float(v["max_rate"])
            sp[SP_ST_BIAS:SP_ST_BIAS + 3] = s.bias
        elif k == ALT:
            sp[SP_ALT_FLOOR], sp[SP_ALT_FRAC] = float(v["noise_floor"]), float(v["noise_fraction"])
            sp[SP_ALT_MAX], sp[SP_ALT_BIAS] = float(v["max_range"]), s.bias
            sp[SP_ALT_BEAM:SP_ALT_BEAM + 3] = s.beam_B
        elif k == DOP:
            sp[SP_DOP_FLOOR], sp[SP_DOP_FRAC] = float(v["noise_floor"]), float(v["noise_fraction"])
            sp[SP_DOP_MAX] = float(v["max_altitude"])
            sp[SP_DOP_BIAS:SP_DOP_BIAS + 3] = s.bias
        else:
            sp[SP_FIX_R], sp[SP_FIX_V] = float(v["position_noise"]), float(v["velocity_noise"])
        parts.append(s.rng.standard_normal(per * samples_due(float(s.rate), n_steps, dt)))
    off[N_SENSORS] = sum(p.size for p in parts)
    w = np.concatenate(parts) if parts else np.zeros(0)
    return sp, bias, w, off


@njit(cache=True)
def truth_after_step(y0, y1, dt, gm, omega, f):  # pragma: no cover - compiled
    """Body rate ``omega`` and specific force ``f`` (body frame) over the step of ``dt`` [s] from
    flat state ``y0`` to ``y1`` (quaternion attitude; module docstring), into ``omega``, ``f``."""
    # rotation_vector(q0, q1): d = q0^* x q1, the shorter way round
    d0, d1, d2, d3 = qmul(y0[6], -y0[7], -y0[8], -y0[9], y1[6], y1[7], y1[8], y1[9])
    if d0 < 0.0:
        d0, d1, d2, d3 = -d0, -d1, -d2, -d3
    n = math.sqrt(d1 * d1 + d2 * d2 + d3 * d3)
    k = 2.0 if n < 1e-15 else 2.0 * math.atan2(n, d0) / n
    omega[0], omega[1], omega[2] = k * d1 / dt, k * d2 / dt, k * d3 / dt
    r0 = y0[0] * y0[0] + y0[1] * y0[1] + y0[2] * y0[2]
    r1 = y1[0] * y1[0] + y1[1] * y1[1] + y1[2] * y1[2]
    c0 = r0 * math.sqrt(r0)
    c1 = r1 * math.sqrt(r1)
    fw = np.empty(3)
    for j in range(3):
        g = 0.5 * (-gm * y0[j] / c0 + -gm * y1[j] / c1)
        fw[j] = (y1[3 + j] - y0[3 + j]) / dt - g
    R = np.empty((3, 3))
    rotation_into(y0[6], y0[7], y0[8], y0[9], R)
    for i in range(3):
        f[i] = R[i, 0] * fw[0] + R[i, 1] * fw[1] + R[i, 2] * fw[2]


@njit(cache=True)
def _take(w, cur, off, k, n):  # pragma: no cover - compiled
    """Start of the next ``n`` normals of sensor ``k`` (its cursor moved on), -1 if it has none left."""
    i = cur[k]
    if i + n > off[k + 1]:
        return -1
    cur[k] = i + n
    return i


@njit(cache=True)
def sample_step(t, y, omega, f, sp, bias, w, off, cur, nxt, last, z, sig, got):  # pragma: no cover - compiled
    """The sensors due at step time ``t`` [s] (the schedule; ``nxt``: each one's next due time,
    ``last``: its last sample time, -1 before one), sampling the truth: position, velocity and
    attitude of flat state ``y``, body rate ``omega``, specific force ``f`` (body frame).

    Per sensor ``k``: ``got[k]`` 0 not due, 1 a measurement ``z[k]`` with noise ``sig[k]``, 2 a
    dropout. Returns False when a sensor ran out of normals (the flight is longer than packed)."""
    R = np.empty((3, 3))
    rotation_into(y[6], y[7], y[8], y[9], R)
    radius = sp[SP_RADIUS]
    for k in range(N_SENSORS):
        got[k] = 0
        rate = sp[SP_RATE + k]
        if rate <= 0.0:
            continue
        period = 1.0 / rate
        if t < nxt[k] - 1e-9 * period:
            continue
        nxt[k] = (math.floor(t * rate + 1e-9) + 1) / rate
        dt = (t if t > 0.0 else 1.0 / rate) if last[k] < 0.0 else t - last[k]
        last[k] = t
        got[k] = 1
        if k == IMU:  # imu.IMU.measure
            walks = 0
            if dt > 0.0 and sp[SP_G_WALK] > 0.0:
                walks += 3
            if dt > 0.0 and sp[SP_A_WALK] > 0.0:
                walks += 3
            i = _take(w, cur, off, k, 6 + walks)
            if i < 0:
                return False
            if dt > 0.0 and sp[SP_G_WALK] > 0.0:
                for j in range(3):
                    bias[j] = bias[j] + sp[SP_G_WALK] * math.sqrt(dt) * w[i + j]
                i += 3
            if dt > 0.0 and sp[SP_A_WALK] > 0.0:
                for j in range(3):
                    bias[3 + j] = bias[3 + j] + sp[SP_A_WALK] * math.sqrt(dt) * w[i + j]
                i += 3
            sg = sp[SP_G_ND] / math.sqrt(dt)
            sa = sp[SP_A_ND] / math.sqrt(dt)
            for j in range(3):
                z[k, j] = omega[j] + bias[j] + sg * w[i + j]
                z[k, 3 + j] = f[j] + bias[3 + j] + sa * w[i + 3 + j]
                sig[k, j] = sg
                sig[k, 3 + j] = sa
        elif k == STAR:  # star_tracker.StarTracker.measure
            i = _take(w, cur, off, k, 3)
            if i < 0:
                return False
            if math.sqrt(omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2]) > sp[SP_ST_MAXRATE]:
                got[k] = 2
                continue
            s = sp[SP_ST_NOISE]
            n0 = sp[SP_ST_BIAS] + s * w[i]
            n1 = sp[SP_ST_BIAS + 1] + s * w[i + 1]
            n2 = sp[SP_ST_BIAS + 2] + s * w[i + 2]
            a = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if a < 1e-12:
                m = math.sqrt(1.0 + 0.25 * a * a)
                e0, e1, e2, e3 = 1.0 / m, 0.5 * n0 / m, 0.5 * n1 / m, 0.5 * n2 / m
            else:
                kk = math.sin(0.5 * a) / a
                e0, e1, e2, e3 = math.cos(0.5 * a), kk * n0, kk * n1, kk * n2
            q0, q1, q2, q3 = qmul(y[6], y[7], y[8], y[9], e0, e1, e2, e3)
            if q0 < 0.0:
                q0, q1, q2, q3 = -q0, -q1, -q2, -q3
            z[k, 0], z[k, 1], z[k, 2], z[k, 3] = q0, q1, q2, q3
            sig[k, 0] = sig[k, 1] = sig[k, 2] = s
        elif k == ALT:  # altimeter.RadarAltimeter.measure
            i = _take(w, cur, off, k, 1)
            if i < 0:
                return False
            srange = -1.0
            if radius > 0.0:
                d = np.empty(3)
                for j in range(3):  # body_to_world: R^T beam
                    d[j] = R[0, j] * sp[SP_ALT_BEAM] + R[1, j] * sp[SP_ALT_BEAM + 1] + R[2, j] * sp[SP_ALT_BEAM + 2]
                rd = y[0] * d[0] + y[1] * d[1] + y[2] * d[2]
                c = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - radius * radius
                disc = rd * rd - c
                if disc >= 0.0:
                    srange = -rd - math.sqrt(disc)
            if srange < 0.0 or srange > sp[SP_ALT_MAX]:
                got[k] = 2
                continue
            sigma = math.hypot(sp[SP_ALT_FLOOR], sp[SP_ALT_FRAC] * srange)
            z[k, 0] = srange + sp[SP_ALT_BIAS] + sigma * w[i]
            sig[k, 0] = sigma
        elif k == DOP:  # doppler.DopplerVelocimeter.measure
            i = _take(w, cur, off, k, 3)
            if i < 0:
                return False
            h = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - radius
            if radius <= 0.0 or not (0.0 < h <= sp[SP_DOP_MAX]):
                got[k] = 2
                continue
            speed = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
            sigma = math.hypot(sp[SP_DOP_FLOOR], sp[SP_DOP_FRAC] * speed)
            for j in range(3):
                vb = R[j, 0] * y[3] + R[j, 1] * y[4] + R[j, 2] * y[5]
                z[k, j] = vb + sp[SP_DOP_BIAS + j] + sigma * w[i + j]
                sig[k, j] = sigma
        else:  # ground_fix.GroundFix.measure
            i = _take(w, cur, off, k, 6)
            if i < 0:
                return False
            for j in range(3):
                z[k, j] = y[j] + sp[SP_FIX_R] * w[i + j]
                z[k, 3 + j] = y[3 + j] + sp[SP_FIX_V] * w[i + 3 + j]
                sig[k, j] = sp[SP_FIX_R]
                sig[k, 3 + j] = sp[SP_FIX_V]
    return True
