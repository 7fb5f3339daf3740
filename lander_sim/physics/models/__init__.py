"""Force and torque models, one module each; a scene switches each one on or off."""
from lander_sim.physics.models.atmosphere import Atmosphere
from lander_sim.physics.models.base import Air, EvalContext, ForceModel, Inputs, Surface, Touchdown
from lander_sim.physics.models.constant_force import ConstantForce
from lander_sim.physics.models.drag_mesh import MeshDrag, sphere_mesh
from lander_sim.physics.models.drag_sphere import SphereDrag
from lander_sim.physics.models.gravity import InverseSquareGravity, UniformGravity
from lander_sim.physics.models.ground import Ground
from lander_sim.physics.models.parachute import ChuteStatus, Parachute
from lander_sim.physics.models.thrusters import Thrusters

__all__ = [
    "Air", "Atmosphere", "ChuteStatus", "ConstantForce", "EvalContext", "ForceModel", "Ground", "Inputs",
    "InverseSquareGravity", "MeshDrag", "Parachute", "SphereDrag", "Surface", "Thrusters",
    "Touchdown", "UniformGravity", "sphere_mesh",
]
