"""Small scene builders shared by the physics tests."""
from __future__ import annotations

from typing import Any

from lander_sim.scenes import Scene, parse_scene


def free_body_scene(inertia: tuple[float, float, float], omega_B: list[float], dt: float, mode: str = "quaternion",
                    models: dict[str, Any] | None = None, **extra: Any) -> Scene:
    """A rigid body rotating about a fixed point with the given models (none: torque free)."""
    data = {
        "name": "free-body",
        "vehicle": {"dry_mass": 1.0, "inertia": list(inertia)},
        "attitude_mode": mode,
        "dt": dt,
        "fixed_pivot": True,
        "initial": {"omega_B": omega_B, "attitude": {"euler_deg": [20.0, 70.0, -40.0]}},
        "models": models or {},
    }
    data.update(extra)
    return parse_scene(data, "free-body.yaml")


import pytest  # noqa: E402


@pytest.fixture
def free_body():
    """The :func:`free_body_scene` builder."""
    return free_body_scene
