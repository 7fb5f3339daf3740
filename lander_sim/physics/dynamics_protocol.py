"""What an integrator needs from a model of motion: the contract between physics and integrators.

The physics side (``lander_sim.physics.dynamics``) builds an object that satisfies
:class:`Dynamics` from a scene's force and torque models; the integrators
(``lander_sim.integrators``) only ever talk to this protocol, so either side can
change without the other. Inputs (throttles, wind, ...) are attributes of the
dynamics object and are **piecewise constant over each step**: the simulation
sets them between steps, never during one.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from lander_sim.physics.state import AttitudeMode


class Dynamics(Protocol):
    """Second-order rigid-body dynamics on the flat state of :mod:`lander_sim.physics.state`."""

    #: ``"quaternion"`` (eq 14 kinematics) or ``"euler"`` (eq 5 kinematics).
    attitude: AttitudeMode
    #: False when translation is switched off (fixed pivot): integrators leave r, v untouched.
    translation: bool
    #: Number of calls to :meth:`accelerations` (cost measure for benchmarks).
    evaluations: int

    def accelerations(self, t: float, y: np.ndarray, out: np.ndarray) -> None:
        """Write ``[a_W (3), omega_dot_B (3)]`` at time ``t`` and state ``y`` into ``out`` (6,).

        ``a_W`` is the translational acceleration in the world frame [m/s^2]
        (eq 7 of the control reference), ``omega_dot_B`` the body angular
        acceleration from Euler's equations (eq 2 of the dynamics reference) [rad/s^2].
        Must not modify ``y``.
        """
        ...

    def fuel_rate(self, t: float, y: np.ndarray) -> float:
        """Fuel mass rate [kg/s] (<= 0) for the current inputs; 0 once the tank is empty."""
        ...
