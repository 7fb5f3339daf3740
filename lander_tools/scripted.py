"""Scripted flights: a scenario, a controller, a timeline and an end condition, in YAML or Python.

A script file (``flights/*.yaml``)::

    name: hover-steps
    description: "Seed 2 scenario 7: demand-altitude steps with the combined law"
    scene: hover                      # scene name, alias or path
    controller: combined-quaternion   # omitted: the scene's autopilot; none: the sim alone
    controller_params: {}             # passed to the controller
    speed: 0                          # real-time factor, 0 = as fast as possible (default)
    lockstep: true                    # default: on when there is a controller
    sim: {publish_rate: 20}           # lander_sim node parameters
    autopilot: {}                     # lander_autopilot node parameters
    record: {storage: mcap, topics: [/clock, /lander/state]}   # both optional
    estimate: false                   # true: the estimator flies beside the sim, the autopilot on its estimate
    end: {time: 60.0, on: [landed, crashed]}                   # time: sim seconds (required)
    timeline:                         # one action per entry, applied at sim time t [s]
      - {t: 0, demand_altitude: 500}
      - {t: 20, demand_altitude: 520}
      - {t: 30, wind: [0, -5, 0]}                               # world frame, m/s
      - {t: 40, controller: altitude-p, params: {k1: 0.1}}
      - {t: 1, throttle: [0, 0.2, 0, 0], until: 6}              # held until `until`
      - {t: 5, stabiliser: true}
      - {t: 5, parachute: true}

In Python, build :class:`Script` directly and call :meth:`Script.run`. Errors name
the file, the entry and the key (:class:`ScriptError`).

Reading and checking a script is plain Python; :meth:`Script.run` imports the launcher
(:mod:`lander_tools.fly.phases`, rclpy) when it flies.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lander_tools.fly.checks import shipped_flights
from lander_tools.fly.plan import ACTION_KINDS, Action, FlightPlan, FlightResult
from lander_yaml import read_yaml

_TOP_KEYS = {"name", "description", "scene", "controller", "controller_params", "speed", "lockstep",
             "sim", "autopilot", "record", "end", "timeline", "compose", "estimate"}


class ScriptError(ValueError):
    """A scripted flight file with a missing or bad key; the message names file, entry and key."""


@dataclass
class Script:
    """A scripted flight (see the module docstring for the meaning of every field)."""

    name: str
    scene: str
    duration: float
    description: str = ""
    controller: str | None = None
    controller_params: dict[str, Any] = field(default_factory=dict)
    speed: float = 0.0
    lockstep: bool | None = None
    sim: dict[str, Any] = field(default_factory=dict)
    autopilot: dict[str, Any] = field(default_factory=dict)
    storage: str = "mcap"
    topics: tuple[str, ...] | None = None
    end_on: tuple[str, ...] = ("landed", "crashed")
    timeline: list[Action] = field(default_factory=list)
    compose: bool = False
    #: Fly on the estimate (``lander fly --estimate``): the scene needs sensors with an IMU.
    estimate: bool = False
    source: Path | None = None

    def plan(self, record: Path | None = None, storage: str | None = None) -> FlightPlan:
        """The launcher's :class:`~lander_tools.fly.plan.FlightPlan` of this script."""
        return FlightPlan(
            scene=self.scene,
            controller=self.controller,
            controller_params=dict(self.controller_params),
            duration=self.duration,
            speed=self.speed,
            lockstep=self.lockstep,
            sim_params=dict(self.sim),
            autopilot_params=dict(self.autopilot),
            record=record,
            storage=storage or self.storage,
            topics=self.topics,
            compose=self.compose,
            estimate=self.estimate,
            timeline=list(self.timeline),
            end_on=self.end_on,
            meta={"script": self.name},
        )

    def run(self, record: Path | None = None, **fly_kwargs: Any) -> FlightResult:
        """Fly the script (recording to ``record`` if given) and return how it ended."""
        from lander_tools.fly.phases import fly

        return fly(self.plan(record), **fly_kwargs)


def is_script(arg: str | Path) -> bool:
    """True when ``arg`` is a YAML file holding a scripted flight (it has a ``scene`` key)."""
    p = Path(arg)
    if p.suffix not in (".yaml", ".yml") or not p.is_file():
        return False
    try:
        data = read_yaml(p, "scripted flight", ScriptError)
    except ScriptError:
        return False  # not a readable script: the scene loader says what is wrong with the file
    return isinstance(data, dict) and "scene" in data and "vehicle" not in data


def _number(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScriptError(f"{where}: expected a finite number, got {v!r}")
    return float(v)


def _action(entry: Any, where: str) -> Action:
    if not isinstance(entry, dict):
        raise ScriptError(f"{where}: expected a mapping like {{t: 5, demand_altitude: 500}}, got {entry!r}")
    if "t" not in entry:
        raise ScriptError(f"{where}: missing key 't' (sim time of the action, s)")
    t = _number(entry["t"], f"{where}.t")
    if t < 0:
        raise ScriptError(f"{where}.t = {t}: must be >= 0")
    kinds = [k for k in entry if k in ACTION_KINDS]
    extra = set(entry) - set(ACTION_KINDS) - {"t", "until", "params"}
    if extra:
        raise ScriptError(f"{where}: unknown key(s) {', '.join(sorted(map(str, extra)))}; actions: {', '.join(ACTION_KINDS)}")
    if len(kinds) != 1:
        raise ScriptError(f"{where}: give exactly one action of {', '.join(ACTION_KINDS)}, got {kinds or 'none'}")
    kind = kinds[0]
    v = entry[kind]
    until = None
    if kind == "demand_altitude":
        v = _number(v, f"{where}.demand_altitude")
    elif kind == "wind":
        if not isinstance(v, list) or len(v) != 3:
            raise ScriptError(f"{where}.wind: expected [x, y, z] in m/s (world frame), got {v!r}")
        v = [_number(x, f"{where}.wind") for x in v]
    elif kind == "throttle":
        if not isinstance(v, list) or not v:
            raise ScriptError(f"{where}.throttle: expected a list of throttles in [0, 1], got {v!r}")
        v = [_number(x, f"{where}.throttle") for x in v]
        if any(not 0.0 <= x <= 1.0 for x in v):
            raise ScriptError(f"{where}.throttle = {v}: every throttle must be in [0, 1]")
        if "until" in entry:
            until = _number(entry["until"], f"{where}.until")
            if until <= t:
                raise ScriptError(f"{where}.until = {until}: must be later than t = {t}")
    elif kind == "controller":
        if not isinstance(v, str) or not v:
            raise ScriptError(f"{where}.controller: expected a controller name, got {v!r}")
    elif kind == "stabiliser" and not isinstance(v, bool):
        raise ScriptError(f"{where}.stabiliser: expected true or false, got {v!r}")
    if "until" in entry and kind != "throttle":
        raise ScriptError(f"{where}.until: only a throttle override has an end time")
    params = entry.get("params", {})
    if not isinstance(params, dict) or (params and kind != "controller"):
        raise ScriptError(f"{where}.params: a mapping, and only with a controller swap")
    return Action(t=t, kind=kind, value=v, until=until, params=dict(params))


def parse_script(data: Any, source: str = "<script>") -> Script:
    """Validate a script mapping (as loaded from YAML) and build the :class:`Script`."""
    if not isinstance(data, dict):
        raise ScriptError(f"{source}: expected a mapping with at least 'scene' and 'end'")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ScriptError(f"{source}: unknown key(s) {', '.join(sorted(map(str, unknown)))}; allowed: {', '.join(sorted(_TOP_KEYS))}")
    for key in ("scene", "end"):
        if key not in data:
            raise ScriptError(f"{source}: missing key {key!r}")
    end = data["end"]
    if not isinstance(end, dict) or "time" not in end:
        raise ScriptError(f"{source}: end: expected {{time: SECONDS, on: [landed, crashed]}}, got {end!r}")
    duration = _number(end["time"], f"{source}: end.time")
    if duration <= 0:
        raise ScriptError(f"{source}: end.time = {duration}: must be > 0")
    on = end.get("on", ["landed", "crashed"])
    if not isinstance(on, list) or any(x not in ("landed", "crashed") for x in on):
        raise ScriptError(f"{source}: end.on = {on!r}: a list of landed / crashed")
    for key in ("sim", "autopilot", "controller_params"):
        if not isinstance(data.get(key, {}), dict):
            raise ScriptError(f"{source}: {key}: expected a mapping of parameters")
    rec = data.get("record", {}) or {}
    if not isinstance(rec, dict) or set(rec) - {"storage", "topics"}:
        raise ScriptError(f"{source}: record: expected {{storage: mcap|sqlite3, topics: [...]}}, got {rec!r}")
    if rec.get("storage", "mcap") not in ("mcap", "sqlite3"):
        raise ScriptError(f"{source}: record.storage = {rec['storage']!r}: choose mcap or sqlite3")
    timeline = data.get("timeline", []) or []
    if not isinstance(timeline, list):
        raise ScriptError(f"{source}: timeline: expected a list of actions")
    speed = _number(data.get("speed", 0.0), f"{source}: speed")
    if speed < 0:
        raise ScriptError(f"{source}: speed = {speed}: must be >= 0 (0 = as fast as possible)")
    ctrl = data.get("controller")
    for key in ("compose", "estimate"):
        if not isinstance(data.get(key, False), bool):
            raise ScriptError(f"{source}: {key}: expected true or false, got {data[key]!r}")
    return Script(
        name=str(data.get("name", Path(source).stem)),
        description=str(data.get("description", "")),
        scene=str(data["scene"]),
        controller=None if ctrl is None else str(ctrl),
        controller_params=dict(data.get("controller_params", {})),
        duration=duration,
        speed=speed,
        lockstep=data.get("lockstep"),
        sim=dict(data.get("sim", {})),
        autopilot=dict(data.get("autopilot", {})),
        storage=rec.get("storage", "mcap"),
        topics=tuple(rec["topics"]) if rec.get("topics") else None,
        end_on=tuple(on),
        timeline=[_action(e, f"{source}: timeline[{i}]") for i, e in enumerate(timeline)],
        compose=bool(data.get("compose", False)),
        estimate=bool(data.get("estimate", False)),
        source=Path(source) if source != "<script>" else None,
    )


def load_script(path: str | Path) -> Script:
    """Read and validate a scripted flight YAML file."""
    p = Path(path)
    return parse_script(read_yaml(p, "scripted flight", ScriptError), str(p))


def check_flight_path(arg: str | Path) -> None:
    """A ``.yaml`` argument that is no file: ScriptError naming it, with the closest shipped flight."""
    p = Path(arg)
    if p.suffix not in (".yaml", ".yml") or p.is_file():
        return
    flights = {f.name: f"flights/{f.name}" for f in shipped_flights()}
    close = difflib.get_close_matches(p.name, list(flights), n=1, cutoff=0.5)
    hint = f"; did you mean {flights[close[0]]!r}?" if close else ""
    raise ScriptError(f"no such flight or scene file {str(arg)!r}{hint}")

