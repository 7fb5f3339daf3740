"""Geometry of the thrust axis shared by the de-orbit law's parts: the attitude that points it,
its slope in the local frame, and the integral action on the axis flown against the one asked.

World frame ``mars`` (planet-centred), local frame ENU (``L``: its axes in world coordinates,
rows, :func:`lander_autopilot.design.translational.local_frame`), SI units.
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.rotation import matrix_to_quat, quat_to_matrix
from lander_sim.physics.state import StateView

from .axis_kernel import HAVE_NUMBA, thrust_axis_quaternion

#: Floor of an axis's vertical part [-] where its slope is taken (:func:`axis_slope`) and where a
#: thrust along it is turned into vertical thrust: a tilt past 60 degrees does not grow the slope
#: or the thrust asked without bound (the descent never flies it: the tilt limit is 0.7 rad).
AXIS_UP_FLOOR = 0.5
#: Largest integral correction of the thrust axis [-] (:class:`AxisIntegral`), its horizontal over
#: vertical part: ~11 degrees, the shortfall measured under the canopy (a 200 km flight in a 4.7 m/s
#: wind flew its thrust axis 11 degrees short of the 22 asked for at its braking's end), so the
#: correction can close that error and not run away (the laws' ``axis_limit``).
AXIS_LIMIT = 0.2
#: [m/s] floor of a speed a direction is taken from (retrograde, along the airflow): keeps the divisor
#: non-zero at rest, where any direction does; a billionth of a metre a second moves no attitude
MIN_SPEED = 1e-9
#: [-] sine of the angle between two axes under which they are taken as parallel (or opposite) in
#: :func:`thrust_axis_attitude`: ~1e-12 rad, far under the attitude law's resolution, where the
#: cross product's direction is rounding noise
PARALLEL_SINE = 1e-12


def axis_slope(axis_L: np.ndarray) -> np.ndarray:
    """An axis's horizontal over its vertical part, ENU ``(east, north)``, the vertical part floored at
    0.5: how :class:`AxisIntegral` compares the axis flown with the one wanted (both must be measured
    alike)."""
    return axis_L[:2] / max(float(axis_L[2]), AXIS_UP_FLOOR)


class AxisIntegral:
    """Integral action on the thrust axis the attitude law flies, against the one asked of it.

    Under the chute's canopy the attitude law (proportional-derivative) flies the thrust axis short
    of its demand: the canopy's torque pulls body +z back toward the airflow, a steady error. The
    correction added to the axis asked for is ``(1 / time)`` times the integral of ``wanted - flown``
    (each the axis's horizontal over its vertical part, ENU ``(east, north)``), at most ``limit`` in
    norm. For a braking's few seconds only: held on through a 30 s hover it set the horizontal loop
    oscillating (:class:`.hover.HoverCapture`).
    """

    def __init__(self, time: float, limit: float) -> None:
        self.time = time  # [s] integral time
        self.limit = limit  # largest correction (horizontal over vertical part of the axis)
        self.bias = np.zeros(2)  # the correction, ENU (east, north) over up
        self._last: tuple[float, np.ndarray] | None = None  # (t, the axis wanted then)

    def pause(self) -> None:
        """Hold the correction; the next :meth:`update` starts a new interval."""
        self._last = None

    def update(self, t: float, q: np.ndarray, L: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """The correction at time ``t`` [s]: ``q`` the attitude (world -> body), ``L`` the local frame's
        axes in world coordinates (rows), ``wanted`` the axis asked for before the correction."""
        flown = axis_slope(L @ quat_to_matrix(q)[2])
        last = self._last
        if last is not None and t > last[0]:
            self.bias += (t - last[0]) / self.time * (last[1] - flown)
            n = float(np.linalg.norm(self.bias))
            if n > self.limit:
                self.bias *= self.limit / n
        self._last = (t, wanted.copy())
        return self.bias.copy()


def thrust_axis_attitude(q: np.ndarray, direction_W: np.ndarray) -> np.ndarray:
    """The attitude (world -> body quaternion) nearest ``q`` with body +z along ``direction_W``.

    The smallest world-frame rotation taking the current body z to the direction, applied to every
    body axis: the yaw about the thrust axis is kept, so the law spends nothing on it. Rodrigues'
    rotation about ``k = z x d / |z x d|`` by ``atan2(|z x d|, z . d)``; computed by the compiled
    :func:`.axis_kernel.thrust_axis_quaternion` (the same arithmetic as
    :func:`thrust_axis_attitude_numpy`, a numpy call's dispatch saved a dozen times a period).
    """
    if not HAVE_NUMBA:  # pragma: no cover - exercised only where numba is absent
        return thrust_axis_attitude_numpy(q, direction_W)
    s, a, b, c = _floats(q)
    x, y, z = _floats(direction_W)
    return np.array(thrust_axis_quaternion(s, a, b, c, x, y, z, PARALLEL_SINE))


def _floats(v: np.ndarray) -> list[float]:
    return v.tolist() if isinstance(v, np.ndarray) else [float(x) for x in v]


def thrust_axis_attitude_numpy(q: np.ndarray, direction_W: np.ndarray) -> np.ndarray:
    """:func:`thrust_axis_attitude` in numpy: the formula the compiled kernel follows, and its
    stand-in without numba."""
    R = quat_to_matrix(q)  # rows: body axes in world coordinates
    z = R[2]
    d = np.asarray(direction_W, float) / np.linalg.norm(direction_W)
    axis = np.cross(z, d)
    s, cth = float(np.linalg.norm(axis)), float(z @ d)
    if s < PARALLEL_SINE:
        if cth > 0:
            return np.array(q, float)
        # opposite: any perpendicular axis does; take body x
        axis, s, cth = R[0], 1.0, -1.0
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    ang = math.atan2(s, cth)
    M = np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * (K @ K)  # Rodrigues
    return matrix_to_quat(R @ M.T)



def norm3(v: np.ndarray) -> float:
    """``|v| = sqrt(v . v)`` [v's unit] of a float 3-vector: ``np.linalg.norm``'s own arithmetic (the
    same BLAS dot product), without its dispatch."""
    return math.sqrt(v.dot(v))


def mean_of(u: np.ndarray) -> float:
    """The mean of a float array, as ``np.mean`` sums it (the same reduction, without its dispatch)."""
    return float(u.sum()) / u.size


def altitude(state: StateView) -> float:
    """``|r_W| - R_mars`` [m]."""
    return norm3(state.r_W) - c.MARS_RADIUS


def climb_rate(state: StateView) -> float:
    """Velocity along the local vertical [m/s], up positive."""
    # R + h rather than |r|: the arithmetic the law's callers use inline, bit for bit
    return float(state.v_W @ state.r_W) / (c.MARS_RADIUS + altitude(state))
