"""Composes the force/torque models a scene switches on into a :class:`Dynamics` (see dynamics_protocol).

``accelerations`` is the hot loop: one context fill (rotation matrix, mass, altitude,
density), then only the models that are on, then Newton (eq 7 of the control
reference) and Euler's equations (eq 2). A model that is off is not in the list and
costs nothing.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.models.base import Air, EvalContext, ForceModel, Inputs
from lander_sim.physics.models.thrusters import Thrusters
from lander_sim.physics.rigid_body import omega_dot
from lander_sim.physics.state import AttitudeMode
from lander_sim.physics.vehicle import Vehicle


class LanderDynamics:
    """Rigid-body dynamics of a vehicle under a list of force/torque models.

    Parameters
    ----------
    vehicle : Vehicle
        Mass and inertia (``I = m diag(k^2)`` at the current mass, or fixed).
    models : sequence of ForceModel
        The models switched on, evaluated in this order.
    attitude : "quaternion" | "euler"
        Attitude representation of the state (eq 14 or eq 5 kinematics, done by the integrator).
    translation : bool
        False for a fixed pivot: the body only rotates about the mount point.
    inputs : Inputs
        Throttles and wind (shared with the simulation, which sets them between steps).
    atmosphere : Air or None
        Density model (:class:`~lander_sim.physics.models.atmosphere.Atmosphere`); None means vacuum
        (``rho = 0``, not evaluated).
    planet_radius : float
        For the altitude in the context [m]; 0 for planet-less scenes.
    """

    def __init__(
        self,
        vehicle: Vehicle,
        models: Sequence[ForceModel],
        attitude: AttitudeMode,
        translation: bool,
        inputs: Inputs,
        atmosphere: Air | None = None,
        planet_radius: float = 0.0,
    ) -> None:
        self.vehicle = vehicle
        self.models: tuple[ForceModel, ...] = tuple(models)
        self.attitude: AttitudeMode = attitude
        self.translation = translation
        self.inputs = inputs
        self.atmosphere = atmosphere
        self.planet_radius = planet_radius
        self.evaluations = 0
        self.thrusters: Thrusters | None = next((m for m in self.models if isinstance(m, Thrusters)), None)
        self.ctx = EvalContext(inputs=inputs)
        self._f_W = np.zeros(3)
        self._f_B = np.zeros(3)
        self._q_B = np.zeros(3)
        # I = m k^2 (scaled by the current mass) or fixed; floats for the hot loop.
        if vehicle.gyration_sq is not None:
            self._k2 = tuple(float(k) for k in vehicle.gyration_sq)
            self._fixed_I: tuple[float, float, float] | None = None
        else:
            self._k2 = (0.0, 0.0, 0.0)
            assert vehicle.inertia_diag is not None  # Vehicle holds exactly one of the two
            ix, iy, iz = (float(i) for i in vehicle.inertia_diag)
            self._fixed_I = (ix, iy, iz)

    def model(self, name: str) -> ForceModel | None:
        """The model switched on under scene key ``name``, or None."""
        return next((m for m in self.models if m.name == name), None)

    def inertia(self, fuel: float) -> tuple[float, float, float]:
        """Principal moments ``(A, B, C)`` [kg m^2] at the given fuel mass."""
        if self._fixed_I is not None:
            return self._fixed_I
        m = self.vehicle.dry_mass + fuel
        k = self._k2
        return (m * k[0], m * k[1], m * k[2])

    def rotation_matrix(self, y: np.ndarray) -> np.ndarray:
        """World-to-body matrix of the state's attitude (eq 13 or eq 3)."""
        if self.attitude == "quaternion":
            return rotation.quat_to_matrix(y[6:10])
        return rotation.euler_to_matrix(y[6:9])

    def fill_context(self, y: np.ndarray) -> EvalContext:
        """Fill the shared context for state ``y`` (also used between steps by the simulation)."""
        ctx = self.ctx
        ctx.y = y
        ctx.R = self.rotation_matrix(y)
        fuel = y[13]
        ctx.mass = self.vehicle.dry_mass + fuel
        if self.planet_radius > 0.0:
            ctx.altitude = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) - self.planet_radius
        if self.atmosphere is not None:
            ctx.rho = self.atmosphere.density(ctx.altitude)
        return ctx

    def accelerations(self, t: float, y: np.ndarray, out: np.ndarray) -> None:
        """``out[0:3] = a_W`` (eq 7 of the control reference), ``out[3:6] = omega_dot_B`` (eq 2)."""
        self.evaluations += 1
        ctx = self.fill_context(y)
        f_W, f_B, q_B = self._f_W, self._f_B, self._q_B
        f_W[:] = 0.0
        f_B[:] = 0.0
        q_B[:] = 0.0
        for m in self.models:
            m.add(ctx, f_W, f_B, q_B)
        if self.translation:
            # Body-frame forces back to world, x_W = R^T x_B, in floats (no temporaries).
            R, inv_m = ctx.R, 1.0 / ctx.mass
            b0, b1, b2 = f_B[0], f_B[1], f_B[2]
            out[0] = (f_W[0] + R[0, 0] * b0 + R[1, 0] * b1 + R[2, 0] * b2) * inv_m
            out[1] = (f_W[1] + R[0, 1] * b0 + R[1, 1] * b1 + R[2, 1] * b2) * inv_m
            out[2] = (f_W[2] + R[0, 2] * b0 + R[1, 2] * b1 + R[2, 2] * b2) * inv_m
        else:
            out[0:3] = 0.0
        A, B, C = self.inertia(y[13])
        omega_dot(A, B, C, y[10:13], q_B, out[3:6])

    def fuel_rate(self, t: float, y: np.ndarray) -> float:
        """Fuel mass rate [kg/s] from the thrusters (0 without thrusters or fuel)."""
        if self.thrusters is None:
            return 0.0
        return self.thrusters.fuel_rate(y, self.inputs.throttles)
