"""The vehicle's look: what a view of a flight draws, and from which numbers.

One description for both views of a flight: the sim node's RViz markers
(:mod:`lander_sim.ros.markers`) and the live Foxglove scene (:mod:`lander_tools.live.scene`).
Each renders it with the primitives its viewer offers (RViz: a sphere, arrows, a line strip;
Foxglove: a box, cylinders, a line, a sphere), at sizes of its own for what this leaves open
(an arrow's shaft, a line's width).

* **body**: the lander, of size ``L`` (:attr:`lander_sim.physics.vehicle.Vehicle.size`) about its
  centre of mass, :data:`BODY_COLOUR`;
* **plumes**: one per thruster, from its point of action ``p_i`` along its exhaust direction ``d_i``
  (body frame, :class:`lander_sim.physics.vehicle.Thruster`; the force is along ``-d_i``), of length
  ``PLUME_LENGTH_PER_SIZE * L * u_i`` at throttle ``u_i`` (none at 0), :data:`PLUME_COLOUR`;
* **parachute**: once deployed, a canopy centred ``PARACHUTE_HEIGHT_PER_SIZE * L`` above the centre
  of mass along the body z axis, ``PARACHUTE_SIZE_PER_SIZE * L`` across, :data:`PARACHUTE_COLOUR`;
* **trail**: the last positions flown (:class:`Trail`), :data:`TRAIL_COLOUR`.

Plain Python and numpy: no ROS, no viewer.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from lander_sim.physics.vehicle import Vehicle

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Colour:
    """RGBA, each in [0, 1] (``a``: opacity)."""

    r: float
    g: float
    b: float
    a: float = 1.0


BODY_COLOUR = Colour(0.8, 0.8, 0.8, 1.0)
#: The flame, a little see-through (a view that hides an unlit plume by its opacity uses 0 and 1).
PLUME_COLOUR = Colour(1.0, 0.5, 0.1, 0.9)
TRAIL_COLOUR = Colour(0.2, 0.6, 1.0, 1.0)
PARACHUTE_COLOUR = Colour(0.9, 0.9, 1.0, 0.7)
#: Plume length at full throttle, in lander sizes.
PLUME_LENGTH_PER_SIZE = 2.0
#: Height of the canopy's centre above the centre of mass (body z), in lander sizes.
PARACHUTE_HEIGHT_PER_SIZE = 4.0
#: The canopy's extent along body x, y, z, in lander sizes.
PARACHUTE_SIZE_PER_SIZE: Vec3 = (4.0, 4.0, 1.5)


@dataclass(frozen=True)
class Plume:
    """One thrust plume in the body frame: from ``start_B`` [m] along the unit ``direction_B``,
    ``length`` [m] long (0 at zero throttle)."""

    start_B: Vec3
    direction_B: Vec3
    length: float
    throttle: float

    @property
    def end_B(self) -> Vec3:
        """The plume's far end, body frame [m]."""
        s, d, n = self.start_B, self.direction_B, self.length
        return (s[0] + n * d[0], s[1] + n * d[1], s[2] + n * d[2])


@dataclass(frozen=True)
class Look:
    """The look of one vehicle: its size ``L`` [m] and its thrusters' ``(p_i, d_i)`` (body frame)."""

    size: float
    thrusters: tuple[tuple[Vec3, Vec3], ...] = ()

    @classmethod
    def of(cls, vehicle: Vehicle) -> Look:
        """The look of ``vehicle``."""
        return cls(float(vehicle.size), tuple((_vec(t.position_B), _vec(t.direction_B)) for t in vehicle.thrusters))

    def plumes(self, throttles: Iterable[float]) -> list[Plume]:
        """One plume per thruster at ``throttles`` (0..1 each), scaled by its throttle."""
        out = []
        for (p_B, d_B), u in zip(self.thrusters, throttles):
            u = float(u)
            out.append(Plume(p_B, d_B, PLUME_LENGTH_PER_SIZE * self.size * max(0.0, u), u))
        return out

    def parachute_centre_B(self) -> Vec3:
        """Centre of the open canopy, body frame [m]."""
        return (0.0, 0.0, PARACHUTE_HEIGHT_PER_SIZE * self.size)

    def parachute_extent(self) -> Vec3:
        """The open canopy's extent along body x, y, z [m]."""
        x, y, z = PARACHUTE_SIZE_PER_SIZE
        return (x * self.size, y * self.size, z * self.size)


class Trail:
    """The last ``length`` positions flown [m], oldest first, in whatever frame the view keeps."""

    def __init__(self, length: int) -> None:
        self._points: deque[Vec3] = deque(maxlen=length)

    def add(self, point: Sequence[float] | np.ndarray) -> None:
        self._points.append((float(point[0]), float(point[1]), float(point[2])))

    def clear(self) -> None:
        self._points.clear()

    def __len__(self) -> int:
        return len(self._points)

    def __iter__(self) -> Iterator[Vec3]:
        return iter(self._points)

    def __getitem__(self, i: int) -> Vec3:
        return self._points[i]


def _vec(v: Sequence[float] | np.ndarray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))
