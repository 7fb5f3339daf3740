"""The checks of a plan before anything starts: scene, controller and flight names, the ``--params``
file. A bad one is one :class:`~lander_tools.fly.plan.LaunchError` line naming it, with the
closest known name. Plain Python: no ROS here."""
from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

from lander_autopilot.controllers.registry import available_controllers
from lander_autopilot.ros.config import SPECS as AP_SPECS
from lander_ros.params import ROS_BUILTIN, check_value
from lander_ros.params import read_params_file as read_sections
from lander_sim.ros.config import SPECS as SIM_SPECS
from lander_sim.scenes import list_scenes, load_scene
from lander_tools.fly.plan import AUTOPILOT_NODE, SIM_NODE, FlightPlan, LaunchError

#: Sections a ``--params`` file may have, and the node each one configures (``/**``: both).
PARAMS_SECTIONS: dict[str, tuple[str, ...]] = {
    SIM_NODE: (SIM_NODE,), f"/{SIM_NODE}": (SIM_NODE,),
    AUTOPILOT_NODE: (AUTOPILOT_NODE,), f"/{AUTOPILOT_NODE}": (AUTOPILOT_NODE,),
    "lander_autopilot": (AUTOPILOT_NODE,), "/lander_autopilot": (AUTOPILOT_NODE,),
    "/**": (SIM_NODE, AUTOPILOT_NODE),
}


def did_you_mean(name: str, choices: list[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest of ``choices`` (difflib), or ``""``."""
    close = difflib.get_close_matches(name, choices, n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else ""


def read_params_file(path: Path) -> dict[str, dict[str, Any]]:
    """The ``--params`` file's parameters per node (``lander_sim``, ``autopilot``).

    Read by the nodes' own reader (:func:`lander_ros.params.read_params_file`), then checked here
    against both nodes' tables before anything starts: sections :data:`PARAMS_SECTIONS`
    (``lander_autopilot`` is the autopilot's package name, accepted for it). An unknown section or
    key is a :class:`LaunchError` naming it and what is allowed (rcl would ignore it without a word).
    """
    specs = {SIM_NODE: SIM_SPECS, AUTOPILOT_NODE: AP_SPECS}
    known = {node: set(s) for node, s in specs.items()}
    sections = read_sections(path, LaunchError, name=f"--params {path}")
    allowed = ", ".join(PARAMS_SECTIONS)
    out: dict[str, dict[str, Any]] = {SIM_NODE: {}, AUTOPILOT_NODE: {}}
    for key, params in sections.items():
        nodes = PARAMS_SECTIONS.get(key)
        if nodes is None:
            raise LaunchError(f"--params {path}: unknown section {key!r}{did_you_mean(key, list(PARAMS_SECTIONS))} "
                              f"(allowed: {allowed})")
        for name, value in params.items():
            for node in nodes:
                if name not in known[node] | ROS_BUILTIN:
                    names = sorted(known[node])
                    raise LaunchError(f"--params {path}: section {key!r}: {node} has no parameter {name!r}"
                                      f"{did_you_mean(str(name), names)} (allowed: {', '.join(names)})")
                if name not in ROS_BUILTIN:
                    reason = check_value(specs[node], name, value)
                    if reason is not None:
                        raise LaunchError(f"--params {path}: section {key!r}: {reason}")
                out[node][name] = value
    return out


def check_plan(plan: FlightPlan) -> str | None:
    """Check every name and file of ``plan`` before anything starts; returns the controller to fly
    (None: the sim alone). A bad scene, controller (also in the timeline) or ``--params`` file is a
    one-line :class:`LaunchError` naming it, with the closest known name."""
    s = str(plan.scene)
    if not (s.endswith((".yaml", ".yml")) or Path(s).is_file()):
        infos = list_scenes()
        if not any(s == i.name or s in i.aliases for i in infos):
            names = [i.name for i in infos] + [a for i in infos for a in i.aliases]
            flights = {p.stem: f"flights/{p.name}" for p in shipped_flights()}
            close = difflib.get_close_matches(s, names + list(flights), n=1, cutoff=0.5)
            hint = f"; did you mean {flights.get(close[0], close[0])!r}?" if close else ""
            raise LaunchError(f"unknown scene {s!r}{hint} ('lander scenes' lists them; scripted flights: flights/*.yaml)")
    try:
        scene = load_scene(s)
    except ValueError as exc:  # a YAML parser's message spans lines: one line for the user
        raise LaunchError(" ".join(str(exc).split())) from None
    if plan.estimate and (scene.sensors is None or "imu" not in scene.sensors):
        raise LaunchError(f"--estimate: scene {s!r} switches no IMU on (sensors.imu), which the estimator "
                          "propagates on; e.g. landing-sensors has one (docs/estimation.md)")
    controller = resolve_controller(plan)
    names = available_controllers()
    wanted = [controller] if controller is not None else []
    wanted += [str(a.value) for a in plan.timeline if a.kind == "controller"]
    for c in wanted:
        if c not in names:
            raise LaunchError(f"unknown controller {c!r}{did_you_mean(c, names)} (known: {', '.join(names)}, or none)")
    if plan.params_file is not None:
        read_params_file(plan.params_file)
    return controller


def controllability_warning(scene_name: str, controller: str | None) -> str | None:
    """One line when ``controller`` flies axes that ``scene_name``'s thrusters cannot control
    (rank of eq 6's controllability matrix of the altitude or the attitude model below its
    size: lander_autopilot.design.report.uncontrollable_axes), naming them; None otherwise.
    Vertical thrusters make no torque about body z (``psi``, ``wz``); scenario 8's one thruster
    reaches a single axis."""
    from lander_autopilot.controllers.registry import controller_axes
    from lander_autopilot.design.report import uncontrollable_axes

    if controller is None:
        return None
    try:
        axes = controller_axes(controller)
        scene = load_scene(scene_name)
    except ValueError:
        return None  # refused elsewhere, with its own line
    short = uncontrollable_axes(scene.vehicle, float(scene.initial_state[13]), axes)
    if not short:
        return None
    parts = "; ".join(f"{a.model} controllability rank {a.rank} of {a.n_states} (the uncontrollable directions "
                      f"involve {', '.join(a.states)})" for a in short)
    held = " (the scene's stabiliser holds the attitude)" if scene.stabiliser else ""
    return (f"warning: with the thrusters of scene {scene.name!r}, controller {controller!r} cannot control every "
            f"axis it flies: {parts}{held}; 'lander design {scene_name}' shows why")


def resolve_controller(plan: FlightPlan) -> str | None:
    """The controller to fly, or ``None`` for the sim alone (``none``, or a scene without autopilot):
    ``--controller``, else the ``controller`` of the ``--params`` file's autopilot section (a gains
    file names the law its gains are for), else the scene's."""
    if plan.controller is not None:
        return None if plan.controller.lower() == "none" else plan.controller
    if plan.params_file is not None:
        named = read_params_file(plan.params_file)[AUTOPILOT_NODE].get("controller")
        if isinstance(named, str) and named:
            return None if named.lower() == "none" else named
    try:
        scene = load_scene(plan.scene)
    except ValueError as exc:
        raise LaunchError(str(exc)) from None
    return None if scene.autopilot is None else scene.autopilot.controller


def scene_label(name: str) -> str:
    """``'hover' (scenario 7)`` for an alias, ``'hover'`` for a name or a file: the scene as the
    user reads it in the first line."""
    for info in list_scenes():
        if name in info.aliases:
            return f"{info.name!r} (scenario {name})"
    return repr(name)


def scene_end_time(name: str) -> float | None:
    """The scene's ``end.max_time`` [s] (None: the flight ends on landing, crash or Ctrl-C)."""
    try:
        return load_scene(name).end_time
    except ValueError as exc:
        raise LaunchError(str(exc)) from None


def shipped_flights() -> list[Path]:
    """The scripted flights shipped in ``flights/``."""
    return sorted((Path(__file__).resolve().parents[2] / "flights").glob("*.yaml"))
