"""Fused velocity-Verlet kernel for the lander model of scenario 7 (numba-compiled when available).

Same equations and, as far as practical, the same floating-point operation order as the
numpy path (:class:`lander_sim.physics.dynamics.LanderDynamics` + :class:`lander_sim.integrators.verlet.VelocityVerlet`):

* gravity ``F_W = -GM m r / |r|^3`` (eq 7 of the control reference);
* exponential atmosphere ``rho = rho0 exp(-h/H)`` below the exosphere, sphere drag
  ``F_W = 1/2 rho Cd A |W| W`` with ``W = wind_W - v_W``;
* thrusters ``F_B = sum_i t_i F_i``, ``Q_B = sum_i t_i (p_i x F_i)``, fuel ``-sum_i t_i burn_i``;
* ``a_W = (F_W + R(q)^T F_B) / m`` (eq 13), Euler's equations (eq 1-2) with ``I = m diag(k^2)``;
* velocity Verlet (seed 1 section 5), quaternion by eq 14 and renormalised (seed 1 task 3);
* Euler-angle mode (``params[P_EULER]``, the eq 5/6 teaching route): ZXZ angles in ``y[6:9]``,
  ``R(E)`` of eq 3, ``E' = J(E) omega`` (eq 5) and ``E'' = J' omega + J omega'`` (eq 6, ``J'``
  of eq 7), with ``sin(theta)`` floored at ``params[P_SIN_FLOOR]`` as
  :func:`lander_sim.physics.rotation._guarded_sin` does, so gimbal lock gives the numpy path's
  finite-but-wrong numbers; ``params[P_PIVOT]``: a fixed pivot (``r``, ``v`` left alone).

Everything is scalar code, so numba compiles it to a loop with no allocation; without numba the
same functions run as (slow) plain Python. A free quaternion lander (every packaged lander scene)
takes :func:`_quaternion_step`: the same operations in the same order on local scalars, with what
is fixed over a call (switches, parameters, wind, the thrusters' summed force, torque and fuel use
at the call's throttles) read once into a tuple, so the state stays in registers through
:func:`verlet_steps`' loop rather than going through arrays numba must assume may overlap.
"""
from __future__ import annotations

import math

import numpy as np

try:  # numba is optional: the numpy Dynamics path is the fallback.
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only where numba is absent
    HAVE_NUMBA = False

    def njit(*args, **kwargs):  # type: ignore[no-redef]  # the stand-in for numba's, same name on purpose
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

# Layout of the ``params`` array. Uniform gravity ``F_W = m g_W`` and a constant force ``F_W`` at
# ``point_B`` (torque ``point_B x R F_W``: the seed-1 rotor) serve the compiled Runge-Kutta methods.
P_GM, P_RPLANET, P_RHO0, P_H, P_EXO, P_CD, P_AREA, P_DRY, P_K1, P_K2, P_K3, P_FIXED_I, P_GRAV, P_ATMO, P_DRAG, P_THRUST, P_RENORM = range(17)
P_UGRAV, P_G0, P_CFORCE, P_CF0, P_CP0 = 17, 18, 21, 22, 25
# Attitude mode and mount, appended so that an all-zero tail is the quaternion, free-flying lander
# every other packer (the batched sweep, bench/speed.py) already builds: 1.0 = ZXZ Euler angles
# (eq 3, 5, 6) / fixed pivot; the floor of |sin theta| travels with the parameters rather than as
# a compile-time global, which numba's cache would freeze (rotation.SIN_THETA_FLOOR may change).
P_EULER, P_PIVOT, P_SIN_FLOOR = 28, 29, 30
N_PARAMS = 31


@njit(cache=True)
def euler_rates_matrix(theta, psi, floor):  # pragma: no cover - compiled
    """``J`` of eq 5 (``E' = J omega``) as ``rotation.euler_rates_matrix``: its first two columns
    ``(J00, J01, J10, J11, J20, J21)``; the third is ``(0, 0, 1)``. ``|sin theta|`` floored at ``floor``."""
    st = math.sin(theta)
    if abs(st) < floor:  # rotation._guarded_sin: finite (and wrong) at gimbal lock, sign kept
        st = floor if st >= 0.0 else -floor
    ct = math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    return sp / st, cp / st, cp, -sp, -ct * sp / st, -ct * cp / st


@njit(cache=True)
def euler_rates_matrix_dot(theta, psi, th_d, ps_d, floor):  # pragma: no cover - compiled
    """``J'`` of eq 7 as ``rotation.euler_rates_matrix_dot`` (same operation order): its first two
    columns ``(D00, D01, D10, D11, D20, D21)``; the third is zero."""
    st = math.sin(theta)
    if abs(st) < floor:
        st = floor if st >= 0.0 else -floor
    ct = math.cos(theta)
    sp, cp = math.sin(psi), math.cos(psi)
    tt = st / ct if ct != 0.0 else math.inf
    return (-sp / (st * tt) * th_d + cp / st * ps_d, -cp / (st * tt) * th_d - sp / st * ps_d,
            -ps_d * sp, -ps_d * cp,
            sp / (st * st) * th_d - ct * cp / st * ps_d, cp / (st * st) * th_d + ct * sp / st * ps_d)


@njit(cache=True)
def euler_rates(y, floor):  # pragma: no cover - compiled
    """``E' = J(E) omega`` (eq 5) of state ``y``: the numpy path's ``J @ omega``, row by row with
    the third column's 0 and 1 multiplied out (a NaN or inf rate propagates as it does there)."""
    j00, j01, j10, j11, j20, j21 = euler_rates_matrix(y[7], y[8], floor)
    w0, w1, w2 = y[10], y[11], y[12]
    return (j00 * w0 + j01 * w1 + 0.0 * w2, j10 * w0 + j11 * w1 + 0.0 * w2, j20 * w0 + j21 * w1 + 1.0 * w2)


@njit(cache=True)
def _accelerations(y, params, force, torque, throttles, wind, out):  # pragma: no cover - compiled
    """``out[0:3] = a_W``, ``out[3:6] = omega_dot_B`` for state ``y``; returns nothing."""
    fuel = y[13]
    mass = params[P_DRY] + fuel
    x, yy, z = y[0], y[1], y[2]
    r2 = x * x + yy * yy + z * z
    fwx = 0.0
    fwy = 0.0
    fwz = 0.0
    if params[P_GRAV] != 0.0:
        k = -params[P_GM] * mass / (r2 * math.sqrt(r2))
        fwx += k * x
        fwy += k * yy
        fwz += k * z
    if params[P_UGRAV] != 0.0:
        fwx += mass * params[P_G0]
        fwy += mass * params[P_G0 + 1]
        fwz += mass * params[P_G0 + 2]
    rho = 0.0
    if params[P_ATMO] != 0.0:
        alt = math.sqrt(x * x + yy * yy + z * z) - params[P_RPLANET]
        if alt <= params[P_EXO]:
            rho = params[P_RHO0] * math.exp(-alt / params[P_H])
    if params[P_DRAG] != 0.0 and rho != 0.0:
        wx, wy, wz = wind[0] - y[3], wind[1] - y[4], wind[2] - y[5]
        kd = 0.5 * rho * params[P_CD] * params[P_AREA] * math.sqrt(wx * wx + wy * wy + wz * wz)
        fwx += kd * wx
        fwy += kd * wy
        fwz += kd * wz
    fbx = 0.0
    fby = 0.0
    fbz = 0.0
    qx = 0.0
    qy = 0.0
    qz = 0.0
    if params[P_THRUST] != 0.0 and fuel > 0.0:
        for i in range(throttles.shape[0]):
            t = throttles[i]
            fbx += t * force[i, 0]
            fby += t * force[i, 1]
            fbz += t * force[i, 2]
            qx += t * torque[i, 0]
            qy += t * torque[i, 1]
            qz += t * torque[i, 2]
    # World-to-body R (columns of R are rows of R^T, used below for R^T F_B).
    if params[P_EULER] != 0.0:
        # R = Rz(psi) Rx(theta) Rz(phi) of the ZXZ angles (eq 3), as rotation.euler_to_matrix.
        phi, theta, psi = y[6], y[7], y[8]
        cf, sf = math.cos(phi), math.sin(phi)
        ct, st = math.cos(theta), math.sin(theta)
        cp, sp = math.cos(psi), math.sin(psi)
        r00 = cp * cf - sp * ct * sf
        r01 = cp * sf + sp * ct * cf
        r02 = sp * st
        r10 = -sp * cf - cp * ct * sf
        r11 = -sp * sf + cp * ct * cf
        r12 = cp * st
        r20 = st * sf
        r21 = -st * cf
        r22 = ct
    else:
        # R(q) of eq 13, as rotation.quat_to_matrix.
        s, a, b, c = y[6], y[7], y[8], y[9]
        r00 = s * s + a * a - b * b - c * c
        r01 = 2.0 * (a * b + s * c)
        r02 = 2.0 * (a * c - s * b)
        r10 = 2.0 * (a * b - s * c)
        r11 = s * s - a * a + b * b - c * c
        r12 = 2.0 * (s * a + b * c)
        r20 = 2.0 * (s * b + a * c)
        r21 = 2.0 * (b * c - s * a)
        r22 = s * s - a * a - b * b + c * c
    if params[P_CFORCE] != 0.0:
        cf0, cf1, cf2 = params[P_CF0], params[P_CF0 + 1], params[P_CF0 + 2]
        fwx += cf0
        fwy += cf1
        fwz += cf2
        g0 = r00 * cf0 + r01 * cf1 + r02 * cf2
        g1 = r10 * cf0 + r11 * cf1 + r12 * cf2
        g2 = r20 * cf0 + r21 * cf1 + r22 * cf2
        p0, p1, p2 = params[P_CP0], params[P_CP0 + 1], params[P_CP0 + 2]
        qx += p1 * g2 - p2 * g1
        qy += p2 * g0 - p0 * g2
        qz += p0 * g1 - p1 * g0
    out[0] = (fwx + (r00 * fbx + r10 * fby + r20 * fbz)) / mass
    out[1] = (fwy + (r01 * fbx + r11 * fby + r21 * fbz)) / mass
    out[2] = (fwz + (r02 * fbx + r12 * fby + r22 * fbz)) / mass
    if params[P_FIXED_I] != 0.0:
        A, B, C = params[P_K1], params[P_K2], params[P_K3]
    else:
        A, B, C = mass * params[P_K1], mass * params[P_K2], mass * params[P_K3]
    w1, w2, w3 = y[10], y[11], y[12]
    out[3] = ((B - C) * w2 * w3 + qx) / A
    out[4] = ((C - A) * w3 * w1 + qy) / B
    out[5] = ((A - B) * w1 * w2 + qz) / C


@njit(cache=True)
def verlet_step(y, dt, params, force, torque, burn, throttles, wind, a0, a1, est):  # pragma: no cover - compiled
    """One velocity-Verlet step of ``dt`` [s] of ``y`` (14,) in place; ``a0``/``a1`` (6,) and ``est`` (14,) are scratch.

    As :class:`lander_sim.integrators.verlet.VelocityVerlet`: quaternion ``q + q'(omega_half) dt``
    (eq 14) then renormalised if ``params[P_RENORM]``; Euler angles (``params[P_EULER]``)
    ``E + J omega dt + E'' dt^2 / 2`` (eq 5, 6) with the full-step rate, never renormalised;
    with ``params[P_PIVOT]`` the position and velocity are not touched (a fixed pivot). A free
    quaternion lander takes the scalar path (:func:`_quaternion_step`: the same operations, the
    scratch arrays unused).
    """
    if params[P_EULER] == 0.0 and params[P_PIVOT] == 0.0:
        verlet_step_quaternion(y, dt, params, force, torque, burn, throttles, wind)
        return
    h = 0.5 * dt
    _accelerations(y, params, force, torque, throttles, wind, a0)
    fuel_rate = 0.0
    if params[P_THRUST] != 0.0 and y[13] > 0.0:
        acc = 0.0
        for i in range(throttles.shape[0]):
            acc += throttles[i] * burn[i]
        fuel_rate = -acc
    w1, w2, w3 = y[10], y[11], y[12]
    wh1 = w1 + h * a0[3]
    wh2 = w2 + h * a0[4]
    wh3 = w3 + h * a0[5]
    if params[P_EULER] != 0.0:
        # eq 5 and eq 6 (J' of eq 7) in verlet.py's order: (E + (J w) dt) + (dt^2 / 2) (J' w + J w').
        floor = params[P_SIN_FLOOR]
        theta, psi = y[7], y[8]
        j00, j01, j10, j11, j20, j21 = euler_rates_matrix(theta, psi, floor)
        e0 = j00 * w1 + j01 * w2 + 0.0 * w3
        e1 = j10 * w1 + j11 * w2 + 0.0 * w3
        e2 = j20 * w1 + j21 * w2 + 1.0 * w3
        d00, d01, d10, d11, d20, d21 = euler_rates_matrix_dot(theta, psi, e1, e2, floor)
        u0, u1, u2 = a0[3], a0[4], a0[5]
        dd0 = (d00 * w1 + d01 * w2 + 0.0 * w3) + (j00 * u0 + j01 * u1 + 0.0 * u2)
        dd1 = (d10 * w1 + d11 * w2 + 0.0 * w3) + (j10 * u0 + j11 * u1 + 0.0 * u2)
        dd2 = (d20 * w1 + d21 * w2 + 0.0 * w3) + (j20 * u0 + j21 * u1 + 1.0 * u2)
        c2 = 0.5 * dt * dt
        y[6] = (y[6] + e0 * dt) + c2 * dd0
        y[7] = (y[7] + e1 * dt) + c2 * dd1
        y[8] = (y[8] + e2 * dt) + c2 * dd2
    else:
        s, a, b, c = y[6], y[7], y[8], y[9]
        # eq 14 with the half-step rate, then q + q' dt (as rotation.quat_dot * dt).
        ds = 0.5 * (-a * wh1 - b * wh2 - c * wh3)
        da = 0.5 * (s * wh1 + b * wh3 - c * wh2)
        db = 0.5 * (s * wh2 + c * wh1 - a * wh3)
        dc = 0.5 * (s * wh3 + a * wh2 - b * wh1)
        s = s + ds * dt
        a = a + da * dt
        b = b + db * dt
        c = c + dc * dt
        if params[P_RENORM] != 0.0:
            nq = math.sqrt(s * s + a * a + b * b + c * c)
            s, a, b, c = s / nq, a / nq, b / nq, c / nq
        y[6], y[7], y[8], y[9] = s, a, b, c
    moving = params[P_PIVOT] == 0.0
    vh0 = vh1 = vh2 = 0.0
    if moving:
        vh0 = y[3] + h * a0[0]
        vh1 = y[4] + h * a0[1]
        vh2 = y[5] + h * a0[2]
        y[0] = y[0] + vh0 * dt
        y[1] = y[1] + vh1 * dt
        y[2] = y[2] + vh2 * dt
    y[13] += fuel_rate * dt
    if y[13] < 0.0:
        y[13] = 0.0
    for j in range(14):
        est[j] = y[j]
    est[10] = w1 + dt * a0[3]
    est[11] = w2 + dt * a0[4]
    est[12] = w3 + dt * a0[5]
    if moving:
        est[3] = y[3] + dt * a0[0]
        est[4] = y[4] + dt * a0[1]
        est[5] = y[5] + dt * a0[2]
    _accelerations(est, params, force, torque, throttles, wind, a1)
    y[10] = wh1 + h * a1[3]
    y[11] = wh2 + h * a1[4]
    y[12] = wh3 + h * a1[5]
    if moving:
        y[3] = vh0 + h * a1[0]
        y[4] = vh1 + h * a1[1]
        y[5] = vh2 + h * a1[2]


@njit(cache=True)
def _call_constants(params, force, torque, burn, throttles, wind):  # pragma: no cover - compiled
    """What stays fixed over one call of :func:`verlet_steps`, as one tuple of floats: the model's
    parameters and switches, the wind, and the thrusters' summed force ``F_B``, torque ``Q_B`` and
    fuel use ``sum_i t_i burn_i`` at the call's throttles (summed in :func:`_accelerations`' order,
    so they are the values it forms at every evaluation)."""
    fbx = fby = fbz = qx = qy = qz = fuel_use = 0.0
    for i in range(throttles.shape[0]):
        t = throttles[i]
        fbx += t * force[i, 0]
        fby += t * force[i, 1]
        fbz += t * force[i, 2]
        qx += t * torque[i, 0]
        qy += t * torque[i, 1]
        qz += t * torque[i, 2]
    for i in range(throttles.shape[0]):
        fuel_use += throttles[i] * burn[i]
    p = params
    return (p[P_GRAV], p[P_GM], p[P_UGRAV], p[P_G0], p[P_G0 + 1], p[P_G0 + 2], p[P_ATMO], p[P_RPLANET], p[P_EXO],
            p[P_RHO0], p[P_H], p[P_DRAG], p[P_CD], p[P_AREA], wind[0], wind[1], wind[2], p[P_THRUST],
            fbx, fby, fbz, qx, qy, qz, fuel_use, p[P_CFORCE], p[P_CF0], p[P_CF0 + 1], p[P_CF0 + 2],
            p[P_CP0], p[P_CP0 + 1], p[P_CP0 + 2], p[P_DRY], p[P_FIXED_I], p[P_K1], p[P_K2], p[P_K3], p[P_RENORM])


@njit(cache=True)
def _accelerations_q(x, yy, z, vx, vy, vz, s, a, b, c, w1, w2, w3, fuel, m):  # pragma: no cover - compiled
    """:func:`_accelerations` of a free quaternion lander on scalars: ``(a_W, omega_dot_B)`` with the
    constants ``m`` of :func:`_call_constants`; the same operations in the same order."""
    mass = m[32] + fuel
    r2 = x * x + yy * yy + z * z
    fwx = 0.0
    fwy = 0.0
    fwz = 0.0
    if m[0] != 0.0:
        k = -m[1] * mass / (r2 * math.sqrt(r2))
        fwx += k * x
        fwy += k * yy
        fwz += k * z
    if m[2] != 0.0:
        fwx += mass * m[3]
        fwy += mass * m[4]
        fwz += mass * m[5]
    rho = 0.0
    if m[6] != 0.0:
        alt = math.sqrt(x * x + yy * yy + z * z) - m[7]
        if alt <= m[8]:
            rho = m[9] * math.exp(-alt / m[10])
    if m[11] != 0.0 and rho != 0.0:
        wx, wy, wz = m[14] - vx, m[15] - vy, m[16] - vz
        kd = 0.5 * rho * m[12] * m[13] * math.sqrt(wx * wx + wy * wy + wz * wz)
        fwx += kd * wx
        fwy += kd * wy
        fwz += kd * wz
    fbx = fby = fbz = qx = qy = qz = 0.0
    if m[17] != 0.0 and fuel > 0.0:
        fbx, fby, fbz, qx, qy, qz = m[18], m[19], m[20], m[21], m[22], m[23]
    r00 = s * s + a * a - b * b - c * c
    r01 = 2.0 * (a * b + s * c)
    r02 = 2.0 * (a * c - s * b)
    r10 = 2.0 * (a * b - s * c)
    r11 = s * s - a * a + b * b - c * c
    r12 = 2.0 * (s * a + b * c)
    r20 = 2.0 * (s * b + a * c)
    r21 = 2.0 * (b * c - s * a)
    r22 = s * s - a * a - b * b + c * c
    if m[25] != 0.0:
        cf0, cf1, cf2 = m[26], m[27], m[28]
        fwx += cf0
        fwy += cf1
        fwz += cf2
        g0 = r00 * cf0 + r01 * cf1 + r02 * cf2
        g1 = r10 * cf0 + r11 * cf1 + r12 * cf2
        g2 = r20 * cf0 + r21 * cf1 + r22 * cf2
        p0, p1, p2 = m[29], m[30], m[31]
        qx += p1 * g2 - p2 * g1
        qy += p2 * g0 - p0 * g2
        qz += p0 * g1 - p1 * g0
    if m[33] != 0.0:
        A, B, C = m[34], m[35], m[36]
    else:
        A, B, C = mass * m[34], mass * m[35], mass * m[36]
    return ((fwx + (r00 * fbx + r10 * fby + r20 * fbz)) / mass, (fwy + (r01 * fbx + r11 * fby + r21 * fbz)) / mass,
            (fwz + (r02 * fbx + r12 * fby + r22 * fbz)) / mass,
            ((B - C) * w2 * w3 + qx) / A, ((C - A) * w3 * w1 + qy) / B, ((A - B) * w1 * w2 + qz) / C)


@njit(cache=True)
def _quaternion_step(state, dt, m):  # pragma: no cover - compiled
    """One step of :func:`verlet_step` for a free quaternion lander on scalars: the 14 state values
    after the step from ``state`` (the same operations in the same order), ``m`` of :func:`_call_constants`."""
    x, yy, z, vx, vy, vz, s, a, b, c, w1, w2, w3, fuel = state
    h = 0.5 * dt
    a0 = _accelerations_q(x, yy, z, vx, vy, vz, s, a, b, c, w1, w2, w3, fuel, m)
    fuel_rate = -m[24] if m[17] != 0.0 and fuel > 0.0 else 0.0
    wh1 = w1 + h * a0[3]
    wh2 = w2 + h * a0[4]
    wh3 = w3 + h * a0[5]
    # eq 14 with the half-step rate, then q + q' dt (as rotation.quat_dot * dt).
    ds = 0.5 * (-a * wh1 - b * wh2 - c * wh3)
    da = 0.5 * (s * wh1 + b * wh3 - c * wh2)
    db = 0.5 * (s * wh2 + c * wh1 - a * wh3)
    dc = 0.5 * (s * wh3 + a * wh2 - b * wh1)
    s = s + ds * dt
    a = a + da * dt
    b = b + db * dt
    c = c + dc * dt
    if m[37] != 0.0:
        nq = math.sqrt(s * s + a * a + b * b + c * c)
        s, a, b, c = s / nq, a / nq, b / nq, c / nq
    vh0 = vx + h * a0[0]
    vh1 = vy + h * a0[1]
    vh2 = vz + h * a0[2]
    x = x + vh0 * dt
    yy = yy + vh1 * dt
    z = z + vh2 * dt
    fuel += fuel_rate * dt
    if fuel < 0.0:
        fuel = 0.0
    a1 = _accelerations_q(x, yy, z, vx + dt * a0[0], vy + dt * a0[1], vz + dt * a0[2], s, a, b, c,
                          w1 + dt * a0[3], w2 + dt * a0[4], w3 + dt * a0[5], fuel, m)
    return (x, yy, z, vh0 + h * a1[0], vh1 + h * a1[1], vh2 + h * a1[2], s, a, b, c,
            wh1 + h * a1[3], wh2 + h * a1[4], wh3 + h * a1[5], fuel)


@njit(cache=True)
def verlet_step_quaternion(y, dt, params, force, torque, burn, throttles, wind):  # pragma: no cover - compiled
    """:func:`verlet_step` of a free quaternion lander only (``params[P_EULER]`` and
    ``params[P_PIVOT]`` zero: the caller checks): the scalar step, small enough for a caller's
    loop (the compiled closed loop) to take inline."""
    out = _quaternion_step((y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9], y[10], y[11], y[12], y[13]),
                           dt, _call_constants(params, force, torque, burn, throttles, wind))
    for j in range(14):
        y[j] = out[j]


@njit(cache=True)
def _quaternion_steps(y, y_prev, n, dt, m, burning, stop2):  # pragma: no cover - compiled
    """:func:`verlet_steps` of a free quaternion lander, the state held in local variables through the loop."""
    state = (y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9], y[10], y[11], y[12], y[13])
    prev = state
    taken = n
    for k in range(n):
        prev = state
        state = _quaternion_step(state, dt, m)
        if (stop2 > 0.0 and state[0] * state[0] + state[1] * state[1] + state[2] * state[2] < stop2) or (
                burning and state[13] <= 0.0):
            taken = k + 1
            break
    for j in range(14):
        y[j] = state[j]
        if n > 0:  # y_prev as verlet_steps leaves it: untouched when no step is taken
            y_prev[j] = prev[j]
    return taken


@njit(cache=True)
def verlet_steps(y, y_prev, n, dt, params, force, torque, burn, throttles, wind, stop_radius):  # pragma: no cover - compiled
    """Advance ``y`` (14,) in place by up to ``n`` velocity-Verlet steps of ``dt`` [s].

    Stops early, after the step in which the lander goes below ``stop_radius`` [m] (0: never)
    or in which the tank runs dry under non-zero throttle, so the caller can handle that event;
    ``y_prev`` then holds the state before that last step. Returns the number of steps taken.
    """
    burning = False
    for i in range(throttles.shape[0]):
        if throttles[i] != 0.0:
            burning = True
    stop2 = stop_radius * stop_radius
    if params[P_EULER] == 0.0 and params[P_PIVOT] == 0.0:
        return _quaternion_steps(y, y_prev, n, dt, _call_constants(params, force, torque, burn, throttles, wind),
                                 burning, stop2)
    a0 = np.empty(6)
    a1 = np.empty(6)
    est = np.empty(14)
    for k in range(n):
        for j in range(14):
            y_prev[j] = y[j]
        verlet_step(y, dt, params, force, torque, burn, throttles, wind, a0, a1, est)
        if stop2 > 0.0 and y[0] * y[0] + y[1] * y[1] + y[2] * y[2] < stop2:
            return k + 1
        if burning and y[13] <= 0.0:
            return k + 1
    return n
