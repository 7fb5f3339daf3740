"""Gains from design to flight: the gains file ``lander design --write`` writes and ``lander fly
--gains`` flies, and ``lander fly --set NAME=VALUE``.

A gains file is a ROS parameters file of the autopilot alone, in the form the node takes
(docs/autopilot_node.md): its ``controller`` and its ``controller_params`` as a YAML mapping
(as ``lander_autopilot.ros.config.dump_controller_params`` writes it, on one line)::

    autopilot:
      ros__parameters:
        controller: combined
        controller_params: "{K_altitude: [[0.13247, 0.26762]], K_attitude: [[...]], design_fuel: 100.0}"

so ``lander fly SCENE --params gains.yaml`` and ``ros2 run mars_lander autopilot_node --ros-args
--params-file gains.yaml`` read it too. The gains are the design's ``K`` given verbatim (the laws'
``K`` parameters skip the pole placement) with the fuel they were designed at (``design_fuel``: the
law rescales ``K`` by ``m / m_design`` in flight so that ``B K``, and with it the closed-loop poles,
stay as designed; docs/control.md). Plain Python: no ROS here.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from lander_autopilot.ros.config import parse_controller_params
from lander_autopilot.ros.loop_stats import format_gains  # noqa: F401 - the one way gains are printed
from lander_ros.params import read_params_file

#: Controllers a gains file can be written for, and the report's gain each parameter takes:
#: parameter name -> (model of the design report, its ``placement`` K).
DESIGN_GAINS: dict[str, dict[str, str]] = {
    "combined": {"K_altitude": "altitude", "K_attitude": "attitude"},
    "altitude": {"K": "altitude"},
    "attitude-euler": {"K": "attitude"},
}
#: Sections a gains file may name the autopilot by (as ``lander fly --params`` accepts them).
AUTOPILOT_SECTIONS = ("autopilot", "/autopilot", "lander_autopilot", "/lander_autopilot")
#: What a gains file's section may hold.
GAINS_KEYS = ("controller", "controller_params")


class GainsError(ValueError):
    """A gains file or ``--set`` that cannot be flown; the message names the file or the setting."""


def design_gains(report: Mapping[str, Any], controller: str) -> dict[str, Any]:
    """The ``controller_params`` that fly the pole-placement gains of ``report``
    (:func:`lander_autopilot.design.report.design_report`) with ``controller``: each ``K`` as
    printed (full precision) and ``design_fuel``, the fuel [kg] the design was made at."""
    if controller not in DESIGN_GAINS:
        raise GainsError(f"--controller {controller!r}: a gains file can be written for "
                         f"{', '.join(DESIGN_GAINS)} (the laws that take the design's K)")
    params: dict[str, Any] = {name: [[float(v) for v in row] for row in report[model]["placement"]["K"]]
                              for name, model in DESIGN_GAINS[controller].items()}
    params["design_fuel"] = float(report["fuel"])
    return params


def gains_text(controller: str, params: Mapping[str, Any], comment: str = "") -> str:
    """The gains file's text: ``comment`` lines, then the autopilot's section."""
    body = yaml.safe_dump({"autopilot": {"ros__parameters": {
        "controller": controller, "controller_params": controller_params_text(params)}}},
        sort_keys=False, width=1_000_000)
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    return head + body


def controller_params_text(params: Mapping[str, Any]) -> str:
    """``params`` as one YAML flow mapping on one line (:func:`dump_controller_params`'s form,
    unwrapped, every float in full: ``repr`` round-trips): the ``controller_params`` of a gains
    file, and what ``lander switch --gains`` and the student page send the autopilot."""
    return yaml.safe_dump(dict(params), default_flow_style=True, sort_keys=True, width=1_000_000).strip()


def read_gains(path: Path) -> tuple[str, dict[str, Any]]:
    """``(controller, controller_params)`` of a gains file; :class:`GainsError` naming the file and
    what is wrong (not a parameters file, another node's section, a key other than
    :data:`GAINS_KEYS`, no controller, parameters that are not a YAML mapping)."""
    label = f"--gains {path}"
    if not Path(path).is_file():
        raise GainsError(f"{label}: no such file")
    sections = read_params_file(path, GainsError, name=label)
    other = [k for k in sections if k not in AUTOPILOT_SECTIONS]
    if other or not sections:
        raise GainsError(f"{label}: a gains file holds the autopilot's section only (one of "
                         f"{', '.join(AUTOPILOT_SECTIONS)}), found {', '.join(map(repr, other)) or 'none'}")
    params: dict[str, Any] = {}
    for section in sections.values():
        params.update(section)
    unknown = sorted(set(params) - set(GAINS_KEYS))
    if unknown:
        raise GainsError(f"{label}: unknown key(s) {', '.join(unknown)}; a gains file holds {' and '.join(GAINS_KEYS)}")
    controller = params.get("controller")
    if not isinstance(controller, str) or not controller:
        raise GainsError(f"{label}: no 'controller' (the law the gains are for)")
    try:
        return controller, parse_controller_params(params.get("controller_params", ""))
    except ValueError as exc:
        raise GainsError(f"{label}: {exc}") from None


def parse_sets(items: Sequence[str]) -> dict[str, Any]:
    """``--set NAME=VALUE`` items as ``{NAME: value}``, each value read as YAML (``0.2``,
    ``[-0.9, -1.1]``, ``null``); :class:`GainsError` naming an item without ``=`` or a bad value."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise GainsError(f"--set {item!r}: expected NAME=VALUE (e.g. --set kp=0.2)")
        try:
            out[name] = yaml.safe_load(text) if text.strip() else None
        except yaml.YAMLError:
            raise GainsError(f"--set {item!r}: the value is not a number, list or word YAML can read") from None
    return out


def check_gains(scene: str, controller: str, params: Mapping[str, Any], what: str) -> None:
    """Build ``controller`` with ``params`` for ``scene``'s vehicle, as the autopilot will; a
    refusal (an unknown name, a gain of the wrong shape for this vehicle, a bad value) is a
    :class:`GainsError` led by ``what`` (the option that gave them)."""
    from lander_autopilot.ros.slot import build_choice

    try:
        build_choice(scene, controller, params)
    except ValueError as exc:
        message = " ".join(str(exc).split())
        raise GainsError(f"{what}: controller {controller!r}: {message.removeprefix(f'controller {controller!r}: ')}"
                         ) from None


def apply_gains(plan: Any, gains: Path | None, sets: Sequence[str], explicit_controller: str | None) -> None:
    """Set ``plan``'s (a :class:`lander_tools.fly.plan.FlightPlan`) controller and parameters from
    ``--gains FILE`` and ``--set`` items, checked by :func:`check_gains`.

    The file names the controller; a ``--controller`` that names another is refused (the gains
    are that law's). ``--set`` alone sets parameters of the controller the flight flies anyway,
    on top of the scene's own parameters when that is the scene's law."""
    from lander_autopilot.ros.config import scene_autopilot
    from lander_sim.scenes import load_scene

    scene = load_scene(plan.scene)
    base = scene_autopilot(scene)
    if gains is not None:
        controller, params = read_gains(gains)
        if explicit_controller is not None and explicit_controller != controller:
            raise GainsError(f"--gains {gains} holds gains for controller {controller!r}, but --controller is "
                             f"{explicit_controller!r}: leave --controller out, or write the gains for it "
                             f"('lander design SCENE --controller {explicit_controller} --write FILE')")
        what = f"--gains {gains}"
    else:
        if plan.controller is None and scene.autopilot is None:
            raise GainsError(f"--set: scene {scene.name!r} flies no autopilot: name the law with --controller")
        controller = plan.controller or base.controller
        if controller.lower() == "none":
            raise GainsError("--set: the flight has no autopilot (--controller none): nothing takes the parameters")
        params = dict(plan.controller_params) or (dict(base.parameters) if controller == base.controller else {})
        what = "--set"
    params.update(parse_sets(sets))
    if sets and gains is not None:
        what += " with --set"
    check_gains(plan.scene, controller, params, what)
    plan.controller = controller
    plan.controller_params = params
