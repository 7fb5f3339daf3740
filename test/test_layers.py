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
CORE = ("lander_sim/physics", "lander_sim/integrators", "lander_sim/scenes", "lander_sim/fast", "lander_sim/sensors",
        "lander_sim/simulation.py", "lander_sim/errors.py", "lander_sim/yaml_file.py", "lander_sim/look.py")
CONTROL = ("lander_autopilot/controllers", "lander_autopilot/design", "lander_autopilot/guidance",
           "lander_autopilot/estimation")
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


# --- no import circles ---------------------------------------------------------------------------

#: Top-level directories whose Python files are the project's modules (tests and benches
#: included: a circle among them is as much a circle).
PROJECT_DIRS = ("lander_sim", "lander_autopilot", "lander_ros", "lander_tools", "lander_interfaces",
                "bench", "launch", "test")
#: Directories the tests and benches put on ``sys.path`` (``import rosutil`` is ``test/rosutil.py``).
PATH_DIRS = ("test",)


def _module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _project_modules() -> dict[str, Path]:
    """Dotted name -> file of every project module (``a/b/__init__.py`` is ``a.b``)."""
    return {_module_name(p): p for d in PROJECT_DIRS if (REPO / d).is_dir()
            for p in sorted((REPO / d).rglob("*.py"))}


def _import_edges(path: Path, modules: dict[str, Path]) -> list[tuple[str, int]]:
    """``(module, line)`` of every project module an import statement of ``path`` names: at the
    top, inside functions, under ``TYPE_CHECKING`` alike. ``from a import b`` names the module
    ``a.b`` when there is one, else ``a``; ``import a.b.c`` the longest project prefix."""
    tree = ast.parse(path.read_text(), str(path))
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    top = path.relative_to(REPO).parts[0]

    def resolve(dotted: str) -> str | None:
        candidates = [dotted] + ([f"{top}.{dotted}"] if top in PATH_DIRS else [])
        for cand in candidates:
            parts = cand.split(".")
            for n in range(len(parts), 0, -1):
                if ".".join(parts[:n]) in modules:
                    return ".".join(parts[:n])
        return None

    out: list[tuple[str, int]] = []
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in modules else module for a in node.names]
        for target in targets:
            resolved = resolve(target)
            if resolved is not None and resolved != name:
                out.append((resolved, node.lineno))
    return out


def import_graph() -> dict[str, dict[str, int]]:
    """module -> {module it imports: line of the first such import}, over every project module."""
    modules = _project_modules()
    graph: dict[str, dict[str, int]] = {}
    for name, path in modules.items():
        edges = graph.setdefault(name, {})
        for target, line in _import_edges(path, modules):
            edges.setdefault(target, line)
    return graph


def import_cycles(graph: dict[str, dict[str, int]]) -> list[tuple[list[str], list[str]]]:
    """``(cycle, component)`` per strongly connected component of more than one module (Tarjan's
    algorithm): the component's modules, sorted, and a shortest cycle ``[a, b, ..., a]`` through
    its first one."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:  # recursion depth is bounded by the module count (a few hundred)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    cycles = []
    for component in sorted(components):
        members, start = set(component), component[0]
        previous: dict[str, str] = {}
        frontier = [start]
        while frontier and start not in previous:  # breadth first, back to the start
            nxt = []
            for v in frontier:
                for w in sorted(graph[v]):
                    if w in members and w not in previous:
                        previous[w] = v
                        nxt.append(w)
            frontier = nxt
        path = [start]
        while True:
            path.append(previous[path[-1]])
            if path[-1] == start:
                break
        cycles.append((path[::-1], component))
    return cycles


def _describe(cycle: list[str], component: list[str], graph: dict[str, dict[str, int]]) -> str:
    modules = _project_modules()
    steps = [f"{a} ({modules[a].relative_to(REPO)}:{graph[a][b]})" for a, b in zip(cycle, cycle[1:])]
    others = [m for m in component if m not in cycle]
    return " -> ".join(steps + [cycle[-1]]) + (f"; in one circle with {', '.join(others)}" if others else "")


def test_no_import_cycles() -> None:
    """No two project modules import each other, directly or around a longer circle; every
    import statement counts (a late import inside a function still ties the modules together,
    and one under ``TYPE_CHECKING`` still names a type of the other)."""
    graph = import_graph()
    cycles = [_describe(c, members, graph) for c, members in import_cycles(graph)]
    assert not cycles, "import cycles (module (file:line of its import) -> module it imports):\n" + "\n".join(cycles)


def test_the_cycle_check_finds_a_circle() -> None:
    """The checker itself: a three-module circle with a late import is found and named in order."""
    graph = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3, "d": 4}, "d": {}}
    assert import_cycles(graph) == [(["a", "b", "c", "a"], ["a", "b", "c"])]
    assert import_cycles({"a": {"b": 1}, "b": {}}) == []
