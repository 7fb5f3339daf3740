"""Fixtures of the node tests: ROS isolation, rclpy in the test process, scene files."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

# Isolation: a domain of our own and loopback-only discovery, unless the suite-wide conftest set them.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

from lander_sim.physics import constants as c

#: Altitude of the test hover scene [m]: high enough that no test reaches the ground.
HOVER_ALTITUDE = 2000.0


def write_scene(directory: Path, name: str, body: dict) -> Path:
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"name": name, **body}))
    return path


@pytest.fixture(scope="session")
def scenes(tmp_path_factory) -> dict[str, Path]:
    """Test scenes, independent of the packaged ones.

    * ``vertical``: upright lander (body z = world z = radial up) at rest 2 km above Mars,
      inverse-square gravity, thrusters, no air: full throttle gives a = 4 T/m - g up.
    * ``canted``: free space, seed-2 canted thrusters, only thruster 0 enabled, at rest.
    """
    d = tmp_path_factory.mktemp("scenes")
    vertical = {
        "description": "test: upright at rest 2 km up, no air",
        "vehicle": {"preset": "lander"},
        "dt": 0.01,
        "initial": {"position_W": [0.0, 0.0, c.MARS_RADIUS + HOVER_ALTITUDE]},
        "models": {"gravity": {"kind": "inverse-square"}, "thrusters": {}},
    }
    canted = {
        "description": "test: free space, one canted thruster",
        "vehicle": {"preset": "lander", "thrusters": "canted", "disabled": [1, 2, 3]},
        "dt": 0.01,
        "initial": {"position_W": [1000.0 * c.MARS_RADIUS, 0.0, 0.0]},
        "models": {"thrusters": {}},
    }
    return {"vertical": write_scene(d, "vertical", vertical), "canted": write_scene(d, "canted", canted)}


@pytest.fixture(scope="module")
def ros():
    """rclpy in the test process (imported here so the pure tests of this folder need no ROS)."""
    import rclpy

    rclpy.init()
    try:
        yield
    finally:
        rclpy.try_shutdown()
