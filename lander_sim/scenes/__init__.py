"""Scenes: named YAML files that switch models on, set the vehicle, initial state and integrator."""
from lander_sim.scenes.loader import (
    AtmosphereConfig,
    ConstantForceConfig,
    DragConfig,
    GravityConfig,
    GroundConfig,
    Models,
    ParachuteConfig,
    Scene,
    SceneError,
    SceneInfo,
    ThrusterFailure,
    list_scenes,
    load_file,
    load_scene,
    parse_scene,
)

__all__ = [
    "AtmosphereConfig", "ConstantForceConfig", "DragConfig", "GravityConfig", "GroundConfig", "Models",
    "ParachuteConfig", "Scene", "SceneError", "SceneInfo", "ThrusterFailure", "list_scenes", "load_file", "load_scene", "parse_scene",
]
