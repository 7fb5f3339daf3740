"""Geometric integrator: Dullweber-Leimkuhler-McLachlan splitting for rotation, Verlet for translation.

Free rigid-body rotation (eq 2 with ``Q = 0``) in body angular momentum ``L_B = I omega_B`` reads
``L_B' = L_B x omega_B`` with energy ``H = sum_i L_i^2 / (2 I_i)``. Splitting ``H`` into its three
terms ``H_i = L_i^2 / (2 I_i)`` gives three flows that are each solved *exactly*: a rotation about
principal axis ``e_i`` at the constant rate ``w_i = L_i / I_i``, under which ``L_B`` turns by
``-w_i tau`` about ``e_i`` and the attitude follows the exponential map
``q <- q x (cos(w_i tau / 2), sin(w_i tau / 2) e_i)`` (eq 14 with constant ``omega``, eq 9-10).
The symmetric composition ``R1(dt/2) R2(dt/2) R3(dt) R2(dt/2) R1(dt/2)`` is the second-order,
symplectic, time-reversible DLM scheme (Dullweber, Leimkuhler & McLachlan, J. Chem. Phys. 107,
5840, 1997). Consequences used by the tests: ``|L_B|`` and the world angular momentum are
conserved to round-off, the energy error is bounded (no drift), and ``|q| = 1`` holds by
construction, with no renormalisation.

Torques and forces enter as Strang kicks around that drift (kick-drift-kick, as velocity Verlet),
so with torques the method is second order; translation is velocity Verlet (section 5).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lander_sim.integrators.base import IntegratorError, check_dt, clamp_fuel, renormalise_quaternion
from lander_sim.integrators.free_rotor import free_rotor_step
from lander_sim.physics.dynamics_protocol import Dynamics
from lander_sim.physics.state import ATT, FUEL, OMEGA_B, R_W, V_W


def principal_inertia(dyn: Dynamics, y: np.ndarray) -> np.ndarray:
    """Principal moments ``(A, B, C)`` [kg m^2] of the body in state ``y``.

    The Dynamics protocol does not carry the inertia; the splitting needs it to tell the
    gyroscopic part of ``omega'`` from the torque part. Accepted: ``dyn.inertia_B(y)`` or
    ``dyn.vehicle.inertia(fuel)`` (:class:`lander_sim.physics.vehicle.Vehicle`).
    """
    fn = getattr(dyn, "inertia_B", None)
    if fn is not None:
        return np.asarray(fn(y), dtype=float)
    vehicle = getattr(dyn, "vehicle", None)
    if vehicle is not None:
        return vehicle.inertia(float(y[FUEL]))
    raise IntegratorError(
        "integrator 'geometric' needs the principal inertia: the dynamics must provide "
        "inertia_B(y) or a 'vehicle' attribute"
    )


def _torque_part(acc_B: np.ndarray, omega_B: np.ndarray, I: np.ndarray) -> np.ndarray:
    """``I^-1 Q``: the body angular acceleration minus the gyroscopic term ``I^-1 (I w x w)`` of eq 2."""
    Iw = I * omega_B
    return acc_B - np.cross(Iw, omega_B) / I


@dataclass
class Geometric:
    """Kick-drift-kick with the exact-flow DLM free-rotor drift; second order, ``|q| = 1`` by construction.

    1. ``a0 = a(t, y)``; kick ``v += a_W dt/2``, ``omega += I^-1 Q dt/2`` (torque part only);
    2. drift ``r += v dt``; ``(q, L_B = I omega)`` by :func:`~lander_sim.integrators.free_rotor.free_rotor_step` over ``dt``;
    3. ``a1`` at the new positions with predicted rates (as velocity Verlet, for drag);
    4. kick with ``a1`` over ``dt/2``.

    Quaternion-attitude scenes only (Euler angles have no exponential map to follow).
    ``renormalise`` defaults to False because nothing needs it; it is there to measure.
    """

    renormalise: bool = False
    #: Step a model that has a compiled form with :func:`lander_sim.fast.rk_kernels.geometric_steps`
    #: (the same splitting in numba); False keeps this numpy code, the reference.
    compiled: bool = True
    name: str = "geometric"
    order: int = 2
    _a0: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)
    _a1: np.ndarray = field(default_factory=lambda: np.zeros(6), repr=False)
    _est: np.ndarray = field(default_factory=lambda: np.zeros(14), repr=False)

    def step(self, dyn: Dynamics, t: float, y: np.ndarray, dt: float) -> None:
        if type(dt) is not float or not dt > 0.0:
            dt = check_dt(dt)
        if dyn.attitude != "quaternion":
            raise IntegratorError(
                f"integrator 'geometric' needs attitude 'quaternion', the scene uses {dyn.attitude!r}; "
                "for Euler angles choose one of: verlet, symplectic-euler, rk4, adaptive"
            )
        if self.compiled and _fast_steps(dyn, y, dt, self.renormalise):
            return
        a0, a1, est = self._a0, self._a1, self._est
        h = 0.5 * dt
        I0 = principal_inertia(dyn, y)
        dyn.accelerations(t, y, a0)
        fuel_rate = dyn.fuel_rate(t, y)
        tau0 = _torque_part(a0[3:6], y[OMEGA_B], I0)
        w_half = y[OMEGA_B] + h * tau0
        if dyn.translation:
            v_half = y[V_W] + h * a0[0:3]
            y[R_W] += dt * v_half
        q = y[ATT]
        s, x, qy, z, L1, L2, L3 = free_rotor_step(
            q[0], q[1], q[2], q[3], I0[0] * w_half[0], I0[1] * w_half[1], I0[2] * w_half[2],
            I0[0], I0[1], I0[2], dt,
        )
        y[6], y[7], y[8], y[9] = s, x, qy, z
        if self.renormalise:
            renormalise_quaternion(y)
        w_drift = np.array((L1 / I0[0], L2 / I0[1], L3 / I0[2]))
        y[FUEL] += fuel_rate * dt
        clamp_fuel(y)
        # Step 3: accelerations at the new attitude/position with predicted rates (cf. verlet.py).
        est[:] = y
        est[OMEGA_B] = w_drift + h * tau0
        if dyn.translation:
            est[V_W] = v_half + h * a0[0:3]
        dyn.accelerations(t + dt, est, a1)
        I1 = principal_inertia(dyn, y)
        y[OMEGA_B] = w_drift + h * _torque_part(a1[3:6], est[OMEGA_B], I1)
        if dyn.translation:
            y[V_W] = v_half + h * a1[0:3]


def _fast_steps(dyn: Dynamics, y: np.ndarray, dt: float, renormalise: bool) -> bool:
    """One compiled step if the model has a compiled form (and numba is there); False otherwise."""
    from lander_sim.fast import HAVE_NUMBA
    from lander_sim.fast.rk_kernels import compiled_model, geometric_steps

    cm = compiled_model(dyn) if HAVE_NUMBA else None
    if cm is None:
        return False
    thr, wind = cm.inputs()
    dyn.evaluations += geometric_steps(y, dt, 1, cm.params, cm.force, cm.torque, cm.burn, thr, wind, cm.translation,
                                       renormalise)
    return True
