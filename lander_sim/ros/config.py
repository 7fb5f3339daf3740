"""Parameters of the simulation node: names, defaults, descriptions and validation.

Plain Python (no rclpy), so the same checks serve the node's set-parameters
callback, the YAML file check at start-up and the unit tests. Every parameter
is declared by the node from :data:`PARAMETERS`; a bad value is refused with a
reason that names the key, the value and what is allowed.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from lander_ros.params import (
    ROS_BUILTIN,
    ParamSpec,
    boolean,
    check_value,
    finite,
    is_number,
    non_negative,
    params_file_overrides,
    positive,
    positive_int,
    string,
)

#: The node's name, which is also the top-level key of a ROS parameters YAML file.
NODE_NAME = "lander_sim"

#: Allowed values of the ``stabiliser`` parameter.
STABILISER_CHOICES = ("scene", "on", "off")


class ConfigError(ValueError):
    """A parameter or parameters-file entry was refused; the message names the key and value."""


def _frame_id(v: Any) -> str | None:
    if not isinstance(v, str) or not v or v.startswith("/") or any(c.isspace() for c in v):
        return "must be a non-empty frame name without a leading '/' or spaces"
    return None


#: ``seed`` parameter value meaning "the scene's own seed" (its ``wind.gust.seed``).
SCENE_SEED = -1


def _seed(v: Any) -> str | None:
    ok = isinstance(v, int) and not isinstance(v, bool) and v >= SCENE_SEED
    return None if ok else f"must be an integer >= 0, or {SCENE_SEED} for the scene's own seed"


def _stabiliser(v: Any) -> str | None:
    return None if v in STABILISER_CHOICES else f"must be one of {', '.join(STABILISER_CHOICES)}"


def _gimbal(v: Any) -> str | None:
    # |sin theta| threshold: 0 means "use the scene's value"; above 1 would flag every attitude.
    return None if is_number(v) and 0.0 <= v < 1.0 else "must be in [0, 1) (0: use the scene's threshold)"


def _flight_nodes(v: Any) -> str | None:
    ok = isinstance(v, str) and all(n.startswith("/") and len(n) > 1 for n in v.split())
    return None if ok else "must list absolute node names separated by spaces, e.g. '/autopilot /lander_fly'"


def _end_on(v: Any) -> str | None:
    from lander_ros.flight_span import parse_end_on

    if not isinstance(v, str):
        return "must be a string"
    try:
        parse_end_on(v)
    except ValueError as exc:
        return f"must list phases separated by commas: {exc}"
    return None


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("scene", "hover", "Scene name, alias or YAML path (lander_sim.scenes.load_scene).", string, True),
    ParamSpec("integrator", "", "Integrator name (lander_sim.integrators.make); empty: the scene's.", string, True),
    ParamSpec("dt", 0.0, "Physics step [s] of sim time; 0: the scene's.", non_negative, True),
    ParamSpec(
        "publish_rate", 50.0, "Output rate [Hz] of sim time: /clock, state, odometry; also the control period.", positive
    ),
    ParamSpec(
        "speed", 1.0, "Real-time factor: 1 paced to the wall clock, N times faster, 0 as fast as possible.", non_negative
    ),
    ParamSpec("lockstep", False, "Advance only when the controller has answered the latest state.", boolean),
    ParamSpec("lockstep_timeout", 1.0, "Wall seconds to wait for a lockstep answer before advancing anyway.", positive),
    ParamSpec(
        "command_timeout", 0.5, "Staleness limit [s, sim time] of a held throttle command; 0 disables.", non_negative
    ),
    ParamSpec("gimbal_threshold", 0.0, "|sin theta| below which gimbal lock is flagged; 0: the scene's.", _gimbal, True),
    ParamSpec("seed", SCENE_SEED, "Seed of the scene's stochastic models (wind gusts, sensors); -1 keeps the scene's own seeds.", _seed),
    ParamSpec("stabiliser", "scene", "Attitude stabiliser: scene (the scene's setting), on or off.", _stabiliser),
    ParamSpec(
        "pause_at", -1.0, "Pause at the first control instant at or after this sim time [s] (once); < 0: never.",
        finite,
    ),
    ParamSpec(
        "end_time", -1.0, "End the flight at the first control instant at or after this sim time [s]: publish "
        "its state and FLIGHT_ENDED, then advance no further until a reset; < 0: no time limit.", finite,
    ),
    ParamSpec(
        "end_on", "", "Touchdown phases that end the flight the same way, comma-separated: landed, crashed; "
        "empty: none.", _end_on,
    ),
    ParamSpec(
        "idle_diagnostics", True, "Publish /diagnostics while started paused, before the first reset, resume or "
        "step; false: a flight's diagnostics start with it (lander fly: the bag holds only the flight's).", boolean,
    ),
    ParamSpec(
        "flight_id", "", "The launched flight this simulator belongs to (lander fly sets it); non-empty: "
        "/lander/throttle is taken only from flight_nodes and the lander verbs, a stranger is refused and counted "
        "(lander_ros.strangers); empty: from anyone.", string, True,
    ),
    ParamSpec(
        "flight_nodes", "/autopilot /lander_fly", "With a flight_id: the flight's own nodes, one throttle "
        "publisher each, separated by spaces.", _flight_nodes, True,
    ),
    ParamSpec("start_paused", False, "Start paused (resume, step or run_until to advance).", boolean, True),
    ParamSpec("world_frame", "mars", "Planet-fixed frame id (the core's world frame).", _frame_id),
    ParamSpec("body_frame", "base_link", "Body frame id (principal axes of the lander).", _frame_id),
    ParamSpec("publish_tf", True, "Broadcast world->body TF when tf2_ros is importable.", boolean),
    ParamSpec("marker_rate", 10.0, "Maximum marker publishing rate [Hz, wall clock].", positive),
    ParamSpec("diagnostics_rate", 1.0, "Diagnostics publishing rate [Hz, wall clock].", positive),
    ParamSpec("trajectory_length", 500, "Points kept in the trajectory marker.", positive_int),
)

SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}


def check_parameter(name: str, value: Any) -> str | None:
    """Reason ``value`` is refused for parameter ``name``, or ``None`` when it is good."""
    return check_value(SPECS, name, value)


def check_change(name: str, value: Any) -> str | None:
    """Reason the running node refuses to set parameter ``name`` to ``value``, or ``None``.

    Besides this node's own parameters, rclpy's ``use_sim_time`` may not be turned on: the
    simulator is the source of sim time, so its node runs on the wall clock.
    """
    if name == "use_sim_time":
        return "the simulator is the clock: use_sim_time must stay false" if value else None
    return check_parameter(name, value)


def check_params_file(path: str | Path) -> dict[str, Any]:
    """Validate a ROS parameters YAML file for this node; return its ``ros__parameters``.

    Raises :class:`ConfigError` naming the file and the unknown key or bad value,
    so a typo fails loudly instead of being ignored by rcl.
    """
    params = params_file_overrides(path, NODE_NAME, ConfigError)
    for name, value in params.items():
        reason = None if name in ROS_BUILTIN else check_parameter(name, value)
        if reason is not None:
            raise ConfigError(f"{path}: {reason}")
    return params


