"""Vehicle presets that scenes refer to (``vehicle: {preset: lander, thrusters: canted}``): geometry lives here once."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.vehicle import Thruster, Vehicle

#: Thruster layouts of the lander: ``standard`` (all exhaust along -z) and seed 2's ``canted``.
THRUSTER_LAYOUTS = ("standard", "canted")
#: Body-frame positions in units of L, numbered anticlockwise seen from +z: (+x,+y), (-x,+y), (-x,-y), (+x,-y).
_POSITIONS = ((0.45, 0.45, -0.2), (-0.45, 0.45, -0.2), (-0.45, -0.45, -0.2), (0.45, -0.45, -0.2))


def lander(thrusters: str = "standard", disabled: tuple[int, ...] = (), size: float = c.LANDER_SIZE) -> Vehicle:
    """The lander of the extended exercise.

    Dry mass 100 kg, 100 kg of fuel, four thrusters at ``L (+-0.45, +-0.45, -0.2)`` of
    ``T_max`` = half the loaded weight at the surface each, burning 0.5 kg/s at full
    throttle; ``I = m diag(0.45, 0.45, 0.3) L^2``. ``canted``: exhaust ``(+-0.25, 0, -1)``
    normalised, the sign of x following the thruster's side (seed 2).
    """
    if thrusters not in THRUSTER_LAYOUTS:
        raise ValueError(f"thrusters must be one of {', '.join(THRUSTER_LAYOUTS)}, got {thrusters!r}")
    ths = []
    for i, p in enumerate(_POSITIONS):
        d = np.array([0.0, 0.0, -1.0])
        if thrusters == "canted":
            d = np.array([math.copysign(0.25, p[0]), 0.0, -1.0])
            d /= np.linalg.norm(d)
        ths.append(
            Thruster(
                position_B=size * np.array(p),
                direction_B=d,
                max_thrust=c.LANDER_MAX_THRUST,
                fuel_rate=c.LANDER_FUEL_RATE,
                enabled=i not in disabled,
            )
        )
    kx, ky, kz = (g * size * size for g in c.LANDER_GYRATION_SQ)
    return Vehicle(
        dry_mass=c.LANDER_DRY_MASS,
        fuel_capacity=c.LANDER_FUEL_CAPACITY,
        thrusters=tuple(ths),
        gyration_sq=(kx, ky, kz),
        size=size,
    )


PRESETS = {"lander": lander}


def disperse(
    vehicle: Vehicle,
    dry_mass_scale: float = 1.0,
    inertia_scale: float = 1.0,
    thrust_scale: tuple[float, ...] | None = None,
) -> Vehicle:
    """``vehicle`` with its true properties off the nominal ones (the robustness-sweep dispersions).

    ``dry_mass * dry_mass_scale``; the inertia (``gyration_sq`` or ``inertia_diag``) times
    ``inertia_scale``; thruster ``i``'s ``max_thrust`` times ``thrust_scale[i]``. All scales > 0
    (checked by the caller, the scene loader, which names the key).
    """
    from dataclasses import replace

    kw: dict[str, Any] = {"dry_mass": vehicle.dry_mass * dry_mass_scale}
    if vehicle.gyration_sq is not None:
        kw["gyration_sq"] = tuple(k * inertia_scale for k in vehicle.gyration_sq)
    elif vehicle.inertia_diag is not None:  # a Vehicle holds exactly one of the two
        kw["inertia_diag"] = tuple(i * inertia_scale for i in vehicle.inertia_diag)
    if thrust_scale is not None:
        kw["thrusters"] = tuple(replace(th, max_thrust=th.max_thrust * s) for th, s in zip(vehicle.thrusters, thrust_scale))
    return replace(vehicle, **kw)
