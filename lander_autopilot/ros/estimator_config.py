"""Parameters of the estimator node (``lander_estimator``): names, defaults, units, validation.

Plain Python (no rclpy): the node's start-up check, its declarations and docs/estimation.md's
parameter table come from :data:`PARAMETERS`. A refused value gets one line naming the parameter,
the value and what is allowed (:class:`ConfigError`).
"""
from __future__ import annotations

import math
from typing import Any

from lander_ros.params import ParamSpec, positive, string

from ..estimation.flights import INITIAL_SIGMA

#: The node's name: also the top-level key of its ROS parameters YAML file.
NODE_NAME = "lander_estimator"
#: The estimate's topics: nav_msgs/Odometry with covariance, and the LanderState the controllers read.
ODOMETRY_TOPIC = "/lander/estimate/odometry"
STATE_TOPIC = "/lander/estimate/state"
ESTIMATE_TOPICS = (ODOMETRY_TOPIC, STATE_TOPIC)
#: ``seed`` value meaning "the scene's ``sensors.seed``".
SCENE_SEED = -1


class ConfigError(ValueError):
    """A parameter value was refused; the message names the parameter and the value."""


def _seed(v: Any) -> str | None:
    ok = isinstance(v, int) and not isinstance(v, bool) and v >= SCENE_SEED
    return None if ok else f"must be an integer >= 0, or {SCENE_SEED} for the scene's sensors.seed"


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("scene", "landing-sensors", "Scene (name, alias or YAML path) the simulator runs: its sensors "
              "(rates, the altimeter's beam, the IMU's noise) and its gravity. It must switch the IMU on.", string,
              read_only=True),
    ParamSpec("seed", SCENE_SEED, "Seed of the initial estimation error (drawn from the initial sigmas); -1: the "
              "scene's sensors.seed. lander fly gives it the simulator's seed.", _seed, read_only=True),
    ParamSpec("initial_position_sigma", float(INITIAL_SIGMA[0]), "Initial position error, 1 sigma per world "
              "axis [m].", positive, read_only=True),
    ParamSpec("initial_velocity_sigma", float(INITIAL_SIGMA[1]), "Initial velocity error, 1 sigma per world "
              "axis [m/s].", positive, read_only=True),
    ParamSpec("initial_attitude_sigma", float(INITIAL_SIGMA[2]), "Initial attitude error, 1 sigma per body "
              "axis [rad].", positive, read_only=True),
    ParamSpec("flight_id", "", "The launched flight this estimator belongs to (lander fly sets it); non-empty: "
              "/lander/state and the sensor topics are taken only from the flight's /lander_sim; empty: from "
              "anyone.", string, read_only=True),
)
SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}


def initial_sigma(values: dict[str, Any]) -> tuple[float, float, float]:
    """``(position [m], velocity [m/s], attitude [rad])`` initial sigmas from the parameter values."""
    out = tuple(float(values[f"initial_{k}_sigma"]) for k in ("position", "velocity", "attitude"))
    assert all(math.isfinite(x) and x > 0 for x in out)
    return out  # type: ignore[return-value]


def parameter_table() -> str:
    """The parameters as a Markdown table (docs/estimation.md, "The estimator node")."""
    rows = ["| parameter | default | meaning |", "| --- | --- | --- |"]
    rows += [f"| `{p.name}` | {p.default!r} | {p.description} |" for p in PARAMETERS]
    return "\n".join(rows)
