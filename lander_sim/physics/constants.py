"""Physical constants of Mars and the lander of the extended exercise (SI units)."""
from __future__ import annotations

import math

G = 6.673e-11  #: gravitational constant [m^3 kg^-1 s^-2], as in the original program
MARS_MASS = 6.42e23  #: [kg]
MARS_RADIUS = 3386e3  #: [m]
GM_MARS = G * MARS_MASS  #: [m^3/s^2]
SURFACE_GRAVITY = GM_MARS / MARS_RADIUS**2  #: [m/s^2], about 3.737

ATMOSPHERE_SURFACE_DENSITY = 0.017  #: [kg/m^3]
ATMOSPHERE_SCALE_HEIGHT = 11000.0  #: [m]
EXOSPHERE_ALTITUDE = 200e3  #: [m]; zero density above

LANDER_SIZE = 1.0  #: L [m]
LANDER_DRY_MASS = 100.0  #: [kg]
LANDER_FUEL_CAPACITY = 100.0  #: [kg] (100 l at 1 kg/l)
#: Per-thruster maximum thrust: half the fully loaded lander's weight at the surface [N] (about 373.7 N).
LANDER_MAX_THRUST = 0.5 * (LANDER_DRY_MASS + LANDER_FUEL_CAPACITY) * SURFACE_GRAVITY
LANDER_FUEL_RATE = 0.5  #: fuel burn per thruster at full throttle [kg/s]
#: Squared radii of gyration [m^2]: I = m * diag(0.45, 0.45, 0.3) for L = 1 m.
LANDER_GYRATION_SQ = (0.45, 0.45, 0.3)
PARACHUTE_RADIUS = 3.0  #: [m]
PARACHUTE_DRAG_COEFFICIENT = 2.0
PARACHUTE_MAX_DRAG = 20e3  #: [N]; the chute is torn off above this
PARACHUTE_MAX_SPEED = 500.0  #: [m/s]; deploying faster than this inside the atmosphere destroys it
SPHERE_DRAG_COEFFICIENT = 1.0
SPHERE_DRAG_AREA = math.pi * LANDER_SIZE**2  #: [m^2]
