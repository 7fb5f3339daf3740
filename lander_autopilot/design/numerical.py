"""Numerical linearisation: central finite differences of the core's nonlinear model (control eq 3-4).

``A_ij = df_i/dx_j``, ``B_ij = df_i/du_j`` at ``(x_e, u_e)`` (eq 4), each column from
``(f(x + h e_j) - f(x - h e_j)) / 2h``: truncation error ``O(h^2 f''')`` plus rounding
``O(eps |f| / h)``.

The nonlinear models are not re-derived here: they are the simulator's own
:class:`~lander_sim.physics.dynamics.LanderDynamics` (gravity, thrusters, Euler's equations)
and the Euler-angle kinematics ``E' = J(E) omega`` (dynamics reference eq 5,
:func:`lander_sim.physics.rotation.euler_rates_matrix`), the map the integrators advance.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from lander_sim.physics.constants import GM_MARS, MARS_RADIUS
from lander_sim.physics.dynamics import LanderDynamics
from lander_sim.physics.models.base import ForceModel, Inputs
from lander_sim.physics.models.gravity import InverseSquareGravity
from lander_sim.physics.models.thrusters import Thrusters
from lander_sim.physics.rotation import euler_rates_matrix
from lander_sim.physics.state import N_STATE
from lander_sim.physics.vehicle import Vehicle

from .attitude import UPRIGHT_EULER

Model = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _dynamics(vehicle: Vehicle, gravity: bool) -> LanderDynamics:
    models: list[ForceModel] = [Thrusters(vehicle)]
    if gravity:
        models.insert(0, InverseSquareGravity(GM_MARS))
    inputs = Inputs(throttles=np.zeros(vehicle.n_thrusters))
    return LanderDynamics(vehicle, models, "euler", True, inputs, planet_radius=MARS_RADIUS)


def attitude_rhs(vehicle: Vehicle, fuel: float) -> Model:
    """Nonlinear ``f(x, u)`` of ``x = [E, omega_B]``, ``u`` = throttles, from the core (no drag, no gravity).

    Gravity exerts no torque on the lander, so leaving it out changes nothing here.
    """
    dyn = _dynamics(vehicle, gravity=False)
    y = np.zeros(N_STATE)
    y[1] = -(MARS_RADIUS + 1e6)
    y[13] = fuel
    acc = np.zeros(6)

    def f(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        y[6:9] = x[0:3]
        y[10:13] = x[3:6]
        dyn.inputs.throttles = np.asarray(u, dtype=float)
        dyn.accelerations(0.0, y, acc)
        return np.concatenate((euler_rates_matrix(x[0:3]) @ x[3:6], acc[3:6]))

    return f


def altitude_rhs(vehicle: Vehicle, fuel: float) -> Model:
    """Nonlinear eq 10 (no drag) from the core: ``f([z, z'], [t]) = [z', a_W . r_hat]``.

    The lander sits upright on the world ``-y`` axis (Euler ``(0, pi/2, 0)``) at distance ``z``
    from the centre, every thruster at throttle ``t``.
    """
    dyn = _dynamics(vehicle, gravity=True)
    y = np.zeros(N_STATE)
    y[6:9] = UPRIGHT_EULER
    y[13] = fuel
    acc = np.zeros(6)
    ones = np.ones(vehicle.n_thrusters)

    def f(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        y[1] = -x[0]
        y[4] = -x[1]
        dyn.inputs.throttles = u[0] * ones
        dyn.accelerations(0.0, y, acc)
        return np.array([x[1], -acc[1]])  # r_hat = -y_W

    return f


def linearise(
    f: Model, x_e: np.ndarray, u_e: np.ndarray, h_x: float | np.ndarray = 1e-5, h_u: float = 1e-5
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of ``x' = f(x, u)`` at ``(x_e, u_e)`` by central differences (eq 4).

    ``h_x`` may be one step or one per state (states of very different scale, e.g. ``z`` in
    metres from the planet's centre, need a larger step).
    """
    x_e = np.asarray(x_e, dtype=float)
    u_e = np.asarray(u_e, dtype=float)
    n, m = x_e.size, u_e.size
    hx = np.broadcast_to(np.asarray(h_x, dtype=float), (n,))
    A = np.empty((n, n))
    B = np.empty((n, m))
    for j in range(n):
        d = np.zeros(n)
        d[j] = hx[j]
        A[:, j] = (f(x_e + d, u_e) - f(x_e - d, u_e)) / (2.0 * hx[j])
    for j in range(m):
        d = np.zeros(m)
        d[j] = h_u
        B[:, j] = (f(x_e, u_e + d) - f(x_e, u_e - d)) / (2.0 * h_u)
    return A, B
