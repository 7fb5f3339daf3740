"""In-flight calibration of the de-orbit laws' models, measured from the flight itself (core code).

* :class:`ThrustCalibration`: the thrust per modelled mass, measured in the de-orbit burn (vacuum).
* :class:`ChuteDragFit`: the air's density scale and the mean wind, fitted to the drag measured
  while coasting under the chute.

Both measure an acceleration as the difference of two velocities a control period apart, minus
gravity (known) and the thrust the law commanded over that period (known to the law): SI units,
world frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np


@dataclass
class ThrustCalibration:
    """The thrust per modelled mass the thrusters really give, measured in the de-orbit burn.

    In vacuum the burn's only other force is gravity, known exactly: over each control period
    ``|dv/dt - g|`` is the thrust acceleration flown, and ``T / m``, with ``T`` the axial thrust
    commanded over that period (``T_v`` times the mean throttle flown) and ``m`` the modelled mass,
    is what the laws' model expected. ``scale``, the ratio of their sums over the burn, folds a
    thrust off its rating and a dry mass off the model into one number (as the drag scale does
    under the chute). The MPC's powered descent plans on it (its thrust bound and throttle
    conversion, :class:`.deorbit_mpc.DeorbitMpcController`), and the scheduled law's braking limb and
    collective use it from the powered descent's start (:class:`.deorbit.DescentToAltitude`).
    Clipped to ``[1 - LIMIT, 1 + LIMIT]``: further off is a fault, not a
    dispersion.
    """

    LIMIT: ClassVar[float] = 0.2
    measured: float = 0.0  # sum of measured thrust accelerations [m/s^2]
    model: float = 0.0  # sum of modelled ones [m/s^2]

    def add(self, dv_dt_W: np.ndarray, gravity_W: np.ndarray, thrust: float, mass: float) -> None:
        """One period: mean acceleration [m/s^2, world], mean gravity over it [m/s^2, world], the
        axial thrust commanded [N] and the modelled mass [kg]."""
        self.measured += float(np.linalg.norm(dv_dt_W - gravity_W))
        self.model += thrust / mass

    @property
    def scale(self) -> float:
        """Measured over modelled thrust acceleration (1 before any period of the burn)."""
        if self.model <= 0.0:
            return 1.0
        return min(max(self.measured / self.model, 1.0 - self.LIMIT), 1.0 + self.LIMIT)


@dataclass(frozen=True)
class AirFit:
    """What :class:`ChuteDragFit` found: ``a_D = -scale K |v - wind_W| (v - wind_W)``.

    scale : measured over modelled drag at the same airspeed (density, drag coefficient and mass
        off the model, folded); wind_W : the mean wind [m/s, world]; rms : the fit's residual
        [m/s^2]; samples : control periods fitted.
    """

    scale: float
    wind_W: np.ndarray
    rms: float
    samples: int


@dataclass
class ChuteDragFit:
    """The drag's scale and the mean wind, by least squares over the coast under the chute.

    Each period gives a measured drag acceleration ``a`` (3 components) at a mean velocity ``v``
    and a modelled ``K = sum(1/2 Cd A) rho_model(h) / m_model`` [1/m]; the model is
    ``a = -s K |v - w| (v - w)`` with four unknowns, ``s`` and the wind ``w``. Why both: the wind's
    vertical part changes the airspeed, and so the drag, by a share that grows as the fall slows.
    A scale alone, learnt at the canopy's terminal speed (~40 m/s), over-predicts the drag of the
    braking below by 0.2-0.35 m/s^2 with 1.1 m/s of downdraft (a dispersed 200 km flight: density
    -12.9 %, ``test_calibration.py``), and the MPC, braking on it at its thrust bound, stopped the
    fall 7 m under the hover. The fall from the
    chute's opening (~180 m/s, inclined) to its terminal speed separates the two: on that case the
    fit flown in the loop gives ``s`` 0.866 and 1.18 m/s of downdraft (true: 0.866 with the dry
    mass's share, 1.13). Solved by Gauss-Newton
    from ``scale0`` and ``wind0`` (at most ``MAX_ITERATIONS``). Over a fall at one speed (a coast
    begun near the canopy's terminal speed, e.g. a flight started under an open chute) the scale
    and the wind's part along the fall are one number and the fit would trade one for the other on
    noise: it is refused unless the speeds span ``MIN_SPAN`` (fastest over slowest).
    """

    MAX_ITERATIONS: ClassVar[int] = 20
    MIN_SPAN: ClassVar[float] = 1.5
    _rows: list[tuple[float, float, float, float, float, float, float]] = field(default_factory=list)

    def add(self, velocity_W: np.ndarray, drag_W: np.ndarray, k: float) -> None:
        """One period: mean velocity [m/s, world], measured drag acceleration [m/s^2, world], ``K`` [1/m]."""
        vx, vy, vz = (float(x) for x in velocity_W)
        ax, ay, az = (float(x) for x in drag_W)
        self._rows.append((float(k), vx, vy, vz, ax, ay, az))

    def solve(self, scale0: float, wind0_W: np.ndarray) -> AirFit | None:
        """The fit (``None`` with fewer than 8 periods, speeds spanning less than ``MIN_SPAN``, or if it
        does not converge to ``s > 0``)."""
        if len(self._rows) < 8:
            return None
        R = np.asarray(self._rows)
        K, V, A = R[:, 0], R[:, 1:4], R[:, 4:7]
        speed = np.linalg.norm(V, axis=1)
        if float(speed.max()) < self.MIN_SPAN * float(speed.min()):
            return None
        p = np.array([scale0, *np.asarray(wind0_W, float)])
        for _ in range(self.MAX_ITERATIONS):
            va = V - p[1:]
            n = np.maximum(np.linalg.norm(va, axis=1), 1e-9)
            model = -(p[0] * K * n)[:, None] * va
            r = (model - A).ravel()
            # d model / d s = -K |va| va; d model / d w = s K (|va| I + va va^T / |va|)
            J = np.empty((len(K), 3, 4))
            J[:, :, 0] = -(K * n)[:, None] * va
            J[:, :, 1:] = (p[0] * K)[:, None, None] * (n[:, None, None] * np.eye(3) + va[:, :, None] * va[:, None, :] / n[:, None, None])
            step = np.linalg.lstsq(J.reshape(-1, 4), -r, rcond=None)[0]
            p = p + step
            if float(np.abs(step).max()) < 1e-6 * max(1.0, float(np.abs(p).max())):
                break
        va = V - p[1:]
        res = -(p[0] * K * np.linalg.norm(va, axis=1))[:, None] * va - A
        if not (p[0] > 0.0 and np.all(np.isfinite(p))):
            return None
        return AirFit(scale=float(p[0]), wind_W=p[1:].copy(), rms=float(math.sqrt(np.mean(res * res))), samples=len(K))
