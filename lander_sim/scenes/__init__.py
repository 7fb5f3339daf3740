"""Scenes: named YAML files that switch models on, set the vehicle, initial state and integrator.

Each model's config and the parsing of its section are the model module's own
(:mod:`lander_sim.physics.models.table`)."""
from lander_sim.scenes.loader import (
    AutopilotSection,
    Models,
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
    "AutopilotSection", "Models", "Scene", "SceneError", "SceneInfo", "ThrusterFailure", "list_scenes", "load_file", "load_scene", "parse_scene",
]
