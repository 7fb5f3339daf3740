"""The controller interface: state + demand in, throttles out (docs/architecture.md, "Contract: controllers").

A controller is built once for a :class:`~lander_sim.physics.vehicle.Vehicle` (all design work,
including any python-control call, happens then) and afterwards only runs :meth:`Controller.update`,
which must be cheap: it is called at 50-100 Hz in sweeps of thousands of flights.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle

#: ZXZ Euler angles (phi, theta, psi) of an upright lander on the -y axis [rad].
UPRIGHT_EULER: tuple[float, float, float] = (0.0, math.pi / 2.0, 0.0)


#: Largest horizontal speed a demand may ask for [m/s]: well beyond anything the lander can fly
#: near the ground (its thrust gives at most ~g of horizontal acceleration); more is a typo.
MAX_DEMAND_SPEED = 200.0


class ControllerError(ValueError):
    """Bad controller request: unknown name, unknown or ill-shaped parameter (the message names it)."""


class DemandError(ValueError):
    """Bad demand: NaN, infinite, or below the ground (the message names the field and value)."""


@dataclass(frozen=True)
class Demand:
    """What the autopilot is asked to hold.

    Attributes
    ----------
    altitude : float
        Demand altitude above the surface, ``|r_W| - R_mars`` [m]; finite and >= 0.
    attitude : tuple of 3 floats
        Demand ZXZ Euler angles ``(phi, theta, psi)`` [rad]; default upright on the -y axis.
    omega_B : tuple of 3 floats
        Demand body rate [rad/s]; default at rest.
    velocity : tuple of 2 floats or None
        Demand horizontal velocity ``(v_east, v_north)`` [m/s] in the local ENU frame
        (``local_enu``, :mod:`lander_autopilot.design.translational`); ``None``: no velocity
        demand (laws that control ground speed then hold it at zero). ``|v| <= MAX_DEMAND_SPEED``.
    """

    altitude: float = 500.0
    attitude: tuple[float, float, float] = UPRIGHT_EULER
    omega_B: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        try:
            alt = float(self.altitude)
        except (TypeError, ValueError):
            raise DemandError(f"demand altitude must be a number in metres, got {self.altitude!r}") from None
        if not math.isfinite(alt):
            raise DemandError(f"demand altitude must be finite, got {self.altitude!r}")
        if alt < 0.0:
            raise DemandError(f"demand altitude {alt} m is below the ground (must be >= 0 m)")
        object.__setattr__(self, "altitude", alt)
        for name in ("attitude", "omega_B"):
            v = getattr(self, name)
            try:
                t = tuple(float(c) for c in v)
            except (TypeError, ValueError):
                raise DemandError(f"demand {name} must be 3 numbers, got {v!r}") from None
            if len(t) != 3 or not all(math.isfinite(c) for c in t):
                raise DemandError(f"demand {name} must be 3 finite numbers, got {v!r}")
            object.__setattr__(self, name, t)
        if self.velocity is not None:
            try:
                vel = tuple(float(c) for c in self.velocity)
            except (TypeError, ValueError):
                raise DemandError(f"demand velocity must be 2 numbers (east, north) in m/s, got {self.velocity!r}") from None
            if len(vel) != 2 or not all(math.isfinite(c) for c in vel):
                raise DemandError(f"demand velocity must be 2 finite numbers (east, north) in m/s, got {self.velocity!r}")
            if math.hypot(*vel) > MAX_DEMAND_SPEED:
                raise DemandError(
                    f"demand velocity {math.hypot(*vel):.6g} m/s is absurd (must be <= {MAX_DEMAND_SPEED:g} m/s)"
                )
            object.__setattr__(self, "velocity", vel)


@dataclass(frozen=True)
class ControlOutput:
    """One control step's result.

    Attributes
    ----------
    throttles : ndarray (N,)
        Commanded throttles, clipped to [0, 1].
    saturated : bool
        True if any throttle was clipped.
    unclipped : ndarray (N,) or None
        The control law's throttles before clipping (diagnostics); optional for plug-ins.
    mode : str or None
        The law's current mode (e.g. ``"braking"``), ``None`` for laws without modes. The node
        publishes it in ``AutopilotStatus.mode`` and each change as a ``MODE_CHANGED`` event.
    requests : tuple of Request
        What the law asks of the vehicle or the crew this step (deploy the parachute, report that
        a safe landing is out of reach); the shell acts on them, a core-only loop too.
    """

    throttles: np.ndarray
    saturated: bool
    unclipped: np.ndarray | None = field(default=None, repr=False)
    mode: str | None = None
    requests: tuple[Request, ...] = ()


#: Request kinds a law may raise (:class:`Request`).
REQUEST_DEPLOY_PARACHUTE = "deploy_parachute"
REQUEST_LANDING_UNREACHABLE = "landing_unreachable"


@dataclass(frozen=True)
class Request:
    """A law's request: ``kind`` (``REQUEST_*``), a one-line ``detail`` and SI ``values``.

    ``deploy_parachute``: the node calls ``/lander/deploy_parachute`` (a core loop calls
    ``Simulation.deploy_parachute``). ``landing_unreachable``: the node publishes a
    ``LANDING_UNREACHABLE`` event on ``/lander/events``. Raised once each, not every step.
    """

    kind: str
    detail: str
    values: tuple[tuple[str, float], ...] = ()


def value_range(u: np.ndarray) -> tuple[float, float]:
    """``(min, max)`` of an array's values as ``u.min()``, ``u.max()`` give them (NaN for both if
    any is NaN), from its Python floats: numpy's reductions cost ~1 us each at a thruster count."""
    vals = u.ravel().tolist()
    if any(map(math.isnan, vals)):
        return math.nan, math.nan
    return float(min(vals)), float(max(vals))


def saturate(u: np.ndarray) -> ControlOutput:
    """Clip throttles to [0, 1] and report whether clipping happened.

    Clipping by rounding-size amounts (a law at rest asking for -1e-15) is not saturation.
    Written with two ufuncs and the range of the floats: ``np.clip``/``np.any`` cost several times
    more per call at this size, and this runs every control step of every flight of a sweep.
    """
    lo, hi = value_range(u)
    t = np.minimum(np.maximum(u, 0.0), 1.0)
    return ControlOutput(throttles=t, saturated=lo < -1e-9 or hi > 1.0 + 1e-9, unclipped=u)


def altitude_and_climb_rate(state: StateView) -> tuple[float, float]:
    """Altitude ``|r_W| - R_mars`` [m] and climb rate ``v_W . r_hat`` [m/s]."""
    x, y, z = state.r_W.tolist()  # Python floats: numpy scalar arithmetic is ~10x slower
    r = math.sqrt(x * x + y * y + z * z)
    vx, vy, vz = state.v_W.tolist()
    return r - MARS_RADIUS, (vx * x + vy * y + vz * z) / r


def wrap_angle(a: float) -> float:
    """Angle in [-pi, pi]: the shortest way round for an angle error."""
    return math.remainder(a, 2.0 * math.pi)


class Controller(ABC):
    """Base of all controllers (built-in and third-party).

    Subclasses set :attr:`name`, do their design in ``__init__`` and implement :meth:`command`,
    the law's throttles before clipping; :meth:`update`, what the shell calls, clips them to
    [0, 1] and flags saturation (a law that also reports a mode or requests overrides it).
    :meth:`reset` clears internal state (integrators, memories).
    """

    name: ClassVar[str] = "controller"
    #: The linear models whose axes the law controls (``"altitude"``: eq 16, ``"attitude"``: eq 28;
    #: :func:`lander_autopilot.design.report.uncontrollable_axes`), so a launcher can say which of
    #: them a scene's thrusters cannot reach; () declares none.
    AXES: ClassVar[tuple[str, ...]] = ()

    def __init__(self, vehicle: Vehicle) -> None:
        self.vehicle = vehicle
        self.n_thrusters = vehicle.n_thrusters

    def reset(self) -> None:  # noqa: B027 - an optional hook, not abstract: stateless laws keep it
        """Forget internal state. Stateless laws have nothing to forget."""

    def diagnostics(self) -> dict[str, float]:
        """Figures of the law's own work (SI units, e.g. a solver's times in s) for the autopilot
        node's ``/diagnostics``, a sweep's row and the benches; none by default."""
        return {}

    def gains(self) -> dict[str, np.ndarray]:
        """The feedback gains in force, by parameter name, as the law takes them (``K`` of
        ``u = u_e - K (x - x_e)``, at the design fuel; in flight the law rescales it by
        ``m / m_design``, docs/control.md): a law's attribute ``K`` when it has one, else none."""
        K = getattr(self, "K", None)
        return {} if K is None else {"K": np.atleast_2d(np.asarray(K, dtype=float))}

    def update(self, t: float, state: StateView, demand: Demand) -> ControlOutput:
        """Throttles for ``state`` at time ``t`` [s] to meet ``demand``, clipped to [0, 1]."""
        return saturate(self.command(t, state, demand))

    @abstractmethod
    def command(self, t: float, state: StateView, demand: Demand) -> np.ndarray:
        """The law's throttles before clipping, shape (N,). Summed laws add these, then clip once."""
