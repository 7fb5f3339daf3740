"""Parameters of the autopilot node: names, descriptions, validation, and the scene's defaults.

Plain Python (no rclpy), so the node's set-parameters callback, its start-up check and the unit
tests share one set of checks. A refused value gets a reason naming the parameter, the value and
what is allowed (a :class:`ConfigError`, a ``ValueError``).

Defaults come from the scene (the same one the simulator runs, parameter ``scene``): its
``autopilot`` section may hold ``controller`` (plug-in name), ``parameters`` (a mapping handed to
the controller) and ``demand_altitude`` [m]. Without that section the node flies
:data:`DEFAULT_CONTROLLER` with its own defaults at :data:`DEFAULT_DEMAND_ALTITUDE`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import yaml

from lander_ros.params import ParamSpec, is_number, positive, string
from lander_sim.scenes import Scene

#: The node's name: also the top-level key of its ROS parameters YAML file.
NODE_NAME = "autopilot"
#: Controller flown when neither the parameter nor the scene names one (seed 2's summed law).
DEFAULT_CONTROLLER = "combined"
#: Demand altitude [m] when the scene gives none: z_e = 500 m of the extended program.
DEFAULT_DEMAND_ALTITUDE = 500.0
#: Keys a scene's ``autopilot`` section may hold.
class ConfigError(ValueError):
    """A parameter value or a scene's autopilot section was refused; the message names key and value."""


def _controller_params(v: Any) -> str | None:
    try:
        parse_controller_params(v)
    except ConfigError as exc:
        return str(exc).removeprefix("parameter 'controller_params' ")
    return None


def _demand_altitude(v: Any) -> str | None:
    """The controllers' own check of a demand altitude (:class:`lander_autopilot.controllers.Demand`)."""
    from lander_autopilot.controllers.base import Demand, DemandError

    if not is_number(v):
        return "must be a number [m]"
    try:
        Demand(altitude=float(v))
    except DemandError as exc:
        return f"refused: {exc}"
    return None


#: ``state_source`` value -> (the topic the autopilot reads its states on, the node that publishes it).
STATE_SOURCES: dict[str, tuple[str, str]] = {
    "truth": ("/lander/state", "/lander_sim"),
    "estimate": ("/lander/estimate/state", "/lander_estimator"),
}


def _state_source(v: Any) -> str | None:
    return None if v in STATE_SOURCES else f"must be one of {', '.join(STATE_SOURCES)}"


#: Defaults None are the scene's (filled in at start-up, scene_autopilot); the node declares each
#: from its spec, and an override given at start-up is checked like a later change.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("scene", None, "Scene (name, alias or YAML path, lander_sim.scenes.load_scene) whose vehicle the "
                             "controllers are built for: the one the simulator runs. Changing it rebuilds the "
                             "controller. Default: hover.", string),
    ParamSpec("controller", None, "Controller plug-in name (entry-point group mars_lander.controllers). "
                                  f"Default: the scene's autopilot controller, else {DEFAULT_CONTROLLER!r}.", string),
    ParamSpec("controller_params", None, "The controller's parameters as a YAML mapping, e.g. "
                                         "'{altitude_poles: [-0.9, -1.1]}'; empty = the controller's defaults. "
                                         "Default: the scene's autopilot parameters.", _controller_params),
    ParamSpec("demand_altitude", None, "Demand altitude above the surface [m], finite and >= 0. "
                                       f"Default: the scene's autopilot demand_altitude, else {DEFAULT_DEMAND_ALTITUDE} m. "
                                       "/lander/demand_altitude sets it too.", _demand_altitude, dynamic_typing=True),
    ParamSpec("state_timeout", None, "Wall-clock seconds without a state on /lander/state after which the "
                                     "status reports the state lost (no command is sent without a state). "
                                     "Default: 1 s.", positive, dynamic_typing=True),
    ParamSpec("flight_id", "", "The launched flight this autopilot belongs to (lander fly sets it); non-empty: "
                               "/lander/state is taken only from the flight's /lander_sim, another publisher is "
                               "refused and counted (lander_ros.strangers); empty: from anyone.", string,
              read_only=True),
    ParamSpec("state_source", "truth", "The state the controller flies on: truth (the simulator's /lander/state) "
                                       "or estimate (the estimator node's /lander/estimate/state, the same message "
                                       "type filled from the navigation filter).", _state_source, read_only=True),
)
SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}
PARAMETER_NAMES: tuple[str, ...] = tuple(p.name for p in PARAMETERS)
#: Parameters whose change rebuilds the controller (atomically swapped in).
CONTROLLER_PARAMETERS = frozenset({"scene", "controller", "controller_params"})
#: Default of ``state_timeout`` [s, wall]: 20 control periods at the slowest usual rate (20 Hz) -
#: long enough not to flap on a loaded 2-core machine, short enough to notice a dead simulator.
DEFAULT_STATE_TIMEOUT = 1.0


def parse_controller_params(text: Any) -> dict[str, Any]:
    """The ``controller_params`` YAML text as a dict (empty text: ``{}``).

    Raises :class:`ConfigError` naming the parameter when the text is not YAML or not a mapping
    with string keys. The values are checked by the controller itself (shape, sign).
    """
    if not isinstance(text, str):
        raise ConfigError(f"parameter 'controller_params' must be a YAML string, got {text!r}")
    if not text.strip():
        return {}
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"parameter 'controller_params' is not valid YAML: {exc}") from None
    if data is None:
        return {}
    if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
        raise ConfigError(
            f"parameter 'controller_params' must be a YAML mapping of parameter names to values, got {data!r}"
        )
    return data


def dump_controller_params(params: Mapping[str, Any]) -> str:
    """Inverse of :func:`parse_controller_params`: one-line YAML flow mapping ("" when empty)."""
    if not params:
        return ""
    return yaml.safe_dump(dict(params), default_flow_style=True, sort_keys=True).strip()


def check_state_timeout(value: Any) -> float:
    """``state_timeout`` as a float [s]; refused unless finite and > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ConfigError(f"parameter 'state_timeout' = {value!r} must be a finite number of seconds > 0")
    return float(value)


def check_string(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise ConfigError(f"parameter {name!r} = {value!r} must be a string")
    return value


@dataclass(frozen=True)
class SceneAutopilot:
    """What a scene asks of the autopilot (its ``autopilot`` section, completed with the defaults)."""

    controller: str = DEFAULT_CONTROLLER
    parameters: Mapping[str, Any] = None  # type: ignore[assignment]  # None: {} (set in __post_init__; a dataclass default cannot be a dict)
    demand_altitude: float = DEFAULT_DEMAND_ALTITUDE

    def __post_init__(self) -> None:
        if self.parameters is None:
            object.__setattr__(self, "parameters", {})


def scene_autopilot(scene: Scene) -> SceneAutopilot:
    """The scene's ``autopilot`` section (validated by the scene loader: ``AutopilotSection``)
    completed with the defaults. The demand itself is validated where it is used
    (:class:`lander_autopilot.controllers.Demand`)."""
    section = scene.autopilot
    if section is None:
        return SceneAutopilot()
    demand = DEFAULT_DEMAND_ALTITUDE if section.demand_altitude is None else section.demand_altitude
    return SceneAutopilot(section.controller, dict(section.parameters), demand)
