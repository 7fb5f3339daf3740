"""Node parameters, one way for both nodes: a spec per parameter, its check, and the overrides a
node is started with, read from its command line as rcl reads them.

Plain Python (no rclpy), so the same checks serve a node's set-parameters callback, its start-up
check and the unit tests. A check returns ``None`` for a good value or a reason saying what is
allowed; :func:`check_value` names the parameter and the value in front of it.

rcl silently ignores an override for a parameter a node never declares (a typo in a parameters
file or after ``-p``): :func:`check_overrides` reads the overrides given to a node (``-p
[node:]name:=value`` / ``--param`` and every ``--params-file`` section for the node: ``node``,
``/node``, ``/**``) and refuses an unknown name or a bad value before the node is built.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from lander_yaml import read_yaml

#: Parameters every ROS 2 node has: accepted anywhere, not checked here.
ROS_BUILTIN = frozenset({"use_sim_time", "start_type_description_service"})


def _accept(_value: Any) -> str | None:
    return None


@dataclass(frozen=True)
class ParamSpec:
    """One node parameter.

    ``default`` fixes the parameter's type (None: filled in at start-up, e.g. from the scene,
    with ``dynamic_typing``); ``check`` returns None for a good value or what is allowed;
    ``read_only`` parameters take effect only at start-up."""

    name: str
    default: Any
    description: str
    check: Callable[[Any], str | None] = _accept
    read_only: bool = False
    dynamic_typing: bool = False


# --- checks ------------------------------------------------------------------------------------


def is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def positive(v: Any) -> str | None:
    return None if is_number(v) and math.isfinite(v) and v > 0 else "must be a finite number > 0"


def non_negative(v: Any) -> str | None:
    return None if is_number(v) and math.isfinite(v) and v >= 0 else "must be a finite number >= 0"


def finite(v: Any) -> str | None:
    return None if is_number(v) and math.isfinite(v) else "must be a finite number"


def string(v: Any) -> str | None:
    return None if isinstance(v, str) else "must be a string"


def boolean(v: Any) -> str | None:
    return None if isinstance(v, bool) else "must be true or false"


def positive_int(v: Any) -> str | None:
    return None if isinstance(v, int) and not isinstance(v, bool) and v > 0 else "must be an integer > 0"


def check_value(specs: Mapping[str, ParamSpec], name: str, value: Any) -> str | None:
    """Why ``value`` is refused for parameter ``name`` (unknown name included), or None."""
    spec = specs.get(name)
    if spec is None:
        return f"unknown parameter {name!r}; known: {', '.join(sorted(specs))}"
    if isinstance(spec.default, float) and is_number(value):
        value = float(value)  # an integer literal for a float parameter, as rcl accepts it
    reason = spec.check(value)
    return None if reason is None else f"parameter {name!r} = {value!r} {reason}"


# --- the overrides a node is started with -----------------------------------------------------


def node_sections(node: str) -> tuple[str, ...]:
    """The sections of a parameters file that configure ``node``, in the order rcl applies them
    (later ones win): ``/**`` (every node), ``node``, ``/node``."""
    return ("/**", node, f"/{node}")


def read_params_file(path: str | Path, error: type[ValueError] = ValueError,
                     name: str | None = None) -> dict[str, dict[str, Any]]:
    """Every section of a ROS parameters file with its ``ros__parameters``: ``{section: {name: value}}``.

    The one reader of parameter files, for both nodes (:func:`params_file_overrides`) and
    ``lander fly --params`` (which then checks the sections and names against both nodes' specs).
    A section is a node's name (``node``, ``/node``) or ``/**`` and holds only a ``ros__parameters``
    mapping; anything else is ``error`` naming the file (as ``name``, default the path) and the
    section."""
    p = Path(path)
    label = str(p) if name is None else name
    data = read_yaml(p, "parameters file", error)
    if not isinstance(data, dict):
        raise error(f"{label}: expected a mapping of sections (a node's name or '/**'), each holding ros__parameters")
    sections: dict[str, dict[str, Any]] = {}
    for key, section in data.items():
        if not isinstance(section, dict) or set(section) != {"ros__parameters"} or not isinstance(
                section["ros__parameters"], dict):
            raise error(f"{label}: section {key!r} must hold only a 'ros__parameters' mapping")
        sections[str(key)] = dict(section["ros__parameters"])
    return sections


def params_file_overrides(path: str | Path, node: str, error: type[ValueError] = ValueError) -> dict[str, Any]:
    """The ``ros__parameters`` a parameters file gives node ``node`` (:func:`node_sections`, later
    ones winning as rcl's do); ``error`` naming the file otherwise."""
    sections = read_params_file(path, error)
    params: dict[str, Any] = {}
    for key in node_sections(node):
        params.update(sections.get(key, {}))
    return params


def command_line_overrides(argv: Sequence[str], node: str,
                           error: type[ValueError] = ValueError) -> dict[str, tuple[Any, str]]:
    """Every override of ``argv``'s ROS arguments (after ``--ros-args``, up to ``--``) for node
    ``node``: ``{name: (value, where)}``, ``where`` naming the file or ``-p``."""
    out: dict[str, tuple[Any, str]] = {}
    ros = False
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--ros-args":
            ros = True
        elif arg == "--":
            ros = False
        elif ros and arg in ("-p", "--param") and i + 1 < len(argv):
            target, sep, value = argv[i + 1].partition(":=")
            owner, _, name = target.rpartition(":")
            if sep and owner in ("", node, f"/{node}"):
                out[name] = (yaml.safe_load(value) if value else "", "-p")
            i += 1
        elif ros and arg == "--params-file" and i + 1 < len(argv):
            for name, value in params_file_overrides(argv[i + 1], node, error).items():
                out[name] = (value, argv[i + 1])
            i += 1
        i += 1
    return out


def check_overrides(specs: Mapping[str, ParamSpec], argv: Sequence[str], node: str,
                    error: type[ValueError] = ValueError) -> dict[str, Any]:
    """The overrides ``argv`` gives ``node``, each checked (:func:`check_value`); ``error`` naming
    the first unknown name or bad value, and where it was given."""
    given = command_line_overrides(argv, node, error)
    for name, (value, where) in given.items():
        if name in ROS_BUILTIN:
            continue
        reason = check_value(specs, name, value)
        if reason is not None:
            raise error(f"{where}: {reason}" if where != "-p" else reason)
    return {name: value for name, (value, _) in given.items()}
