"""The layers (docs/architecture.md): dependencies point inward only, tools -> ROS shells ->
controllers -> core, what both nodes' shells share lives in ``lander_ros`` (neither node's
package) and the YAML reader every layer uses in ``lander_yaml``, below them all. Read from the
source with ``ast`` (every import statement, also those inside functions), so a late import
cannot hide an arrow pointing outward."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ROS = ("rclpy", "lander_interfaces", "std_msgs", "geometry_msgs", "nav_msgs", "sensor_msgs", "std_srvs",
       "rosgraph_msgs", "diagnostic_msgs", "visualization_msgs", "rcl_interfaces", "builtin_interfaces", "foxglove")
CORE = ("lander_sim/physics", "lander_sim/integrators", "lander_sim/scenes", "lander_sim/fast",
        "lander_sim/simulation.py", "lander_sim/errors.py", "lander_sim/yaml_file.py")
CONTROL = ("lander_autopilot/controllers", "lander_autopilot/design", "lander_autopilot/guidance")
PROJECT = ("lander_sim", "lander_ros", "lander_autopilot", "lander_tools", "lander_yaml")


def _modules(*paths: str) -> list[Path]:
    out: list[Path] = []
    for p in paths:
        path = REPO / p
        out += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    return out


def _imports(path: Path) -> set[str]:
    """Every module named by an import statement in ``path`` (relative imports resolved)."""
    tree = ast.parse(path.read_text(), str(path))
    package = ".".join(path.relative_to(REPO).with_suffix("").parts[:-1])
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                names.add(".".join(base + ([node.module] if node.module else [])))
            elif node.module:
                names.add(node.module)
    return names


def _outward(paths: tuple[str, ...], forbidden: tuple[str, ...]) -> list[str]:
    bad = []
    for path in _modules(*paths):
        for name in sorted(_imports(path)):
            if any(name == f or name.startswith(f + ".") for f in forbidden):
                bad.append(f"{path.relative_to(REPO)} imports {name}")
    return bad


@pytest.mark.parametrize(("paths", "forbidden"), [
    pytest.param(CORE, (*ROS, "lander_sim.ros", "lander_sim.node", "lander_ros", "lander_autopilot", "lander_tools"),
                 id="the core: no ROS, no shell, no controllers, no tools"),
    pytest.param(CONTROL, (*ROS, "lander_sim.ros", "lander_sim.node", "lander_ros", "lander_autopilot.ros",
                           "lander_autopilot.node", "lander_tools"),
                 id="the controllers and design library: no ROS, no shell, no tools"),
    pytest.param(("lander_autopilot",), ("lander_sim.ros", "lander_sim.node", "lander_tools"),
                 id="the autopilot: nothing of the simulator's shell (shared parts are lander_ros's)"),
    pytest.param(("lander_sim",), ("lander_autopilot", "lander_tools"),
                 id="the simulator: nothing of the autopilot or the tools"),
    pytest.param(("lander_ros",), ("lander_sim", "lander_autopilot", "lander_tools"),
                 id="lander_ros: neither node's package"),
    pytest.param(("lander_yaml",), (*ROS, *(p for p in PROJECT if p != "lander_yaml")),
                 id="lander_yaml: below every layer (PyYAML only)"),
])
def test_dependencies_point_inward(paths: tuple[str, ...], forbidden: tuple[str, ...]) -> None:
    assert _outward(paths, forbidden) == []
