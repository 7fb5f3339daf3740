"""Altitude model of the lander (control reference eq 9-17) and its hover throttle (eq 14).

State ``x = [z, z']`` with ``z = |r_W|`` the distance from the planet's centre (eq 9),
input ``u = [t]``, one throttle shared by all thrusters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.vehicle import Vehicle

from . import DesignError


def vertical_thrust(vehicle: Vehicle) -> float:
    """``T_v`` [N]: total thrust along the body ``+z`` axis at full throttle.

    Each thruster pushes with ``-d_i T_i`` (body frame), so its vertical share is
    ``-d_i . z_B T_i``; canted thrusters give less than ``N T_max`` (the reference's
    "new T_v value" of section 4.2, task 1). Disabled thrusters give nothing.
    """
    return float(sum(-t.direction_B[2] * t.max_thrust for t in vehicle.thrusters if t.enabled))


def hover_throttle(vehicle: Vehicle, fuel: float, radius: float) -> float:
    """Equilibrium throttle ``t_e = G M m / (T_v z_e^2)`` (eq 14) at distance ``radius`` [m] from the centre."""
    tv = vertical_thrust(vehicle)
    if tv <= 0.0:
        raise DesignError(f"vehicle has no upward thrust (T_v = {tv} N): cannot hover")
    return GM_MARS * vehicle.mass(fuel) / (tv * radius * radius)


@dataclass(frozen=True)
class AltitudeModel:
    """Linear altitude model ``dx/dt = A dx + B du`` about a hover (eq 16).

    Attributes
    ----------
    A : ndarray (2, 2)
        ``[[0, 1], [a21, 0]]``; ``a21 = 2GM/z_e^3`` (eq 15) if the gravity gradient is kept,
        else 0 (eq 16's approximation).
    B : ndarray (2, 1)
        ``[[0], [T_v / m]]`` [1/s^2 per unit throttle].
    z_e : float
        Equilibrium distance from the planet's centre [m].
    t_e : float
        Hover throttle (eq 14).
    T_v, mass : float
        Vertical thrust [N] and mass [kg] used.
    """

    A: np.ndarray
    B: np.ndarray
    z_e: float
    t_e: float
    T_v: float
    mass: float


def altitude_model(
    vehicle: Vehicle, fuel: float, altitude: float, gravity_gradient: bool = False
) -> AltitudeModel:
    """Linearise eq 10 about a hover at ``altitude`` [m] above the surface (eq 13-16).

    ``gravity_gradient=False`` gives eq 16 (gravity taken as constant with altitude, the
    reference's choice); ``True`` keeps eq 15's ``2GM/z_e^3`` term, which is what a
    finite-difference linearisation of eq 10 finds (about 2.2e-6 s^-2 near the surface).
    """
    if not np.isfinite(altitude) or altitude < 0.0:
        raise DesignError(f"altitude must be a finite number >= 0 m, got {altitude!r}")
    z_e = MARS_RADIUS + altitude
    tv = vertical_thrust(vehicle)
    t_e = hover_throttle(vehicle, fuel, z_e)
    m = vehicle.mass(fuel)
    a21 = 2.0 * GM_MARS / z_e**3 if gravity_gradient else 0.0
    A = np.array([[0.0, 1.0], [a21, 0.0]])
    B = np.array([[0.0], [tv / m]])
    return AltitudeModel(A=A, B=B, z_e=z_e, t_e=t_e, T_v=tv, mass=m)


def altitude_rhs(x: np.ndarray, u: np.ndarray, vehicle: Vehicle, fuel: float) -> np.ndarray:
    """Nonlinear eq 10 without drag: ``[z', -GM/z^2 + T_v t / m]`` for ``x = [z, z']``, ``u = [t]``."""
    z, zd = x
    return np.array([zd, -GM_MARS / (z * z) + vertical_thrust(vehicle) * u[0] / vehicle.mass(fuel)])


def balanced_thrust(vehicle: Vehicle) -> tuple[float, float]:
    """The most thrust along body ``+z`` the thrusters give with no torque: ``(T [N], fuel flow [kg/s])``.

    ``max sum_i (-d_i . z_B) T_i t_i`` subject to ``M t = 0`` (:func:`.attitude.thrust_torque_matrix`)
    and ``0 <= t_i <= 1``, a linear programme. For the nominal lander's symmetric thrusters it is
    :func:`vertical_thrust` at full throttle; a thruster off its rating or its cant makes full
    throttle on all of them a torque, which a law that holds its attitude must cancel, so a sustained
    burn gets less (e.g. 0.95 of ``T_v`` with +-3 % of thrust and 0.5 degrees of cant per thruster).
    The point-mass yardstick with this bound is the least fuel the rigid vehicle can reach with no
    other torque; under a canopy it is not a bound (its torque can cancel the thrusters'): dispersed
    flights of the de-orbit sweeps measure down to 0.98 x it.
    """
    from scipy.optimize import linprog

    from .attitude import thrust_torque_matrix

    axial = np.array([-t.direction_B[2] * t.max_thrust if t.enabled else 0.0 for t in vehicle.thrusters])
    flow = np.array([t.fuel_rate if t.enabled else 0.0 for t in vehicle.thrusters])
    M = thrust_torque_matrix(vehicle)
    # the torque rows scaled to the thrust's: the equality's tolerance is then a fraction of the thrust
    scale = max(float(np.abs(M).max()), 1e-12) / max(float(np.abs(axial).max()), 1e-12)
    res = linprog(-axial, A_eq=M / scale, b_eq=np.zeros(3), bounds=[(0.0, 1.0)] * len(axial), method="highs")
    if res.status != 0:
        raise DesignError(f"balanced thrust: the linear programme failed ({res.message})")
    t = np.clip(res.x, 0.0, 1.0)
    return float(axial @ t), float(flow @ t)
