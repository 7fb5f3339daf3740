"""Scene files: YAML -> validated, frozen :class:`Scene`.

Every error is a :class:`SceneError` naming the file, the key path
(``hover.yaml: models.drag.kind``) and what was expected. Unknown keys are errors.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lander_sim.integrators import REGISTRY as INTEGRATORS
from lander_sim.physics import constants as c
from lander_sim.physics import rotation
from lander_sim.physics.models.ground import TouchdownLimits
from lander_sim.physics.models.table import MODELS
from lander_sim.physics.state import AttitudeMode, pack
from lander_sim.physics.vehicle import Vehicle
from lander_sim.physics.wind import GustConfig
from lander_sim.scenes import vehicles
from lander_sim.sensors.suite import SensorsConfig, parse_sensors
from lander_sim.yaml_file import Reader
from lander_yaml import read_yaml

SCENE_DIR = Path(__file__).resolve().parent


class SceneError(ValueError):
    """A scene file is missing, unreadable or invalid; the message names file, key and expectation."""


@dataclass(frozen=True)
class SceneInfo:
    """Name, aliases (the original scenario numbers) and one-line description of a packaged scene."""

    name: str
    aliases: tuple[str, ...]
    description: str
    path: Path


@dataclass(frozen=True)
class ThrusterFailure:
    """Thruster ``thruster`` (index into the vehicle's thrusters) stops for good at sim time ``time`` [s]:
    from the first step starting at or after ``time`` it produces nothing and burns nothing."""

    thruster: int
    time: float


@dataclass(frozen=True)
class AutopilotSection:
    """The scene's ``autopilot`` section, parsed once here for everyone (the autopilot node, the
    launcher, sweeps): the controller plug-in to fly (by name), its parameters (checked by the
    controller itself) and the demand altitude [m] (None: the autopilot's default)."""

    controller: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    demand_altitude: float | None = None


#: Keys of a scene's ``autopilot`` section.
AUTOPILOT_KEYS = ("controller", "parameters", "demand_altitude")


@dataclass(frozen=True)
class Models:
    """The models a scene switches on: each one's config (its module's dataclass) by its key
    under ``models:``, in the order of :data:`lander_sim.physics.models.table.MODELS`. A model
    that is off is absent."""

    configs: Mapping[str, Any] = field(default_factory=dict)

    def get(self, key: str) -> Any | None:
        """The config of model ``key`` (e.g. ``"gravity"``), or None when it is off."""
        return self.configs.get(key)

    def __contains__(self, key: object) -> bool:
        return key in self.configs

    def with_config(self, key: str, config: Any) -> Models:
        """A copy with model ``key``'s config replaced (the loader puts ``touchdown`` into the ground's)."""
        return Models({k: (config if k == key else v) for k, v in self.configs.items()})


@dataclass(frozen=True)
class Scene:
    """A validated scene. ``initial_state`` is the flat ``y`` of :mod:`lander_sim.physics.state`.

    ``translation`` False is a fixed pivot (scene key ``fixed_pivot: true``).
    ``wind_W`` [m/s] is the mean wind, world frame (scene key ``wind_W`` or ``wind.mean_W``);
    ``gust`` the optional turbulence about it (``wind.gust``, :mod:`lander_sim.physics.wind`);
    ``thruster_failures`` the scheduled failures (``vehicle.failures``);
    ``end_time`` [s] the optional ``end.max_time``;
    ``sensors`` the sensors switched on (``sensors:``, :mod:`lander_sim.sensors.suite`), None for none.
    """

    name: str
    description: str
    vehicle: Vehicle
    initial_state: np.ndarray
    attitude: AttitudeMode
    integrator: str
    dt: float
    models: Models
    integrator_options: Mapping[str, Any] = field(default_factory=dict)
    translation: bool = True
    stabiliser: bool = False
    autopilot: AutopilotSection | None = None
    gimbal_threshold: float = 1e-3
    wind_W: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gust: GustConfig | None = None
    thruster_failures: tuple[ThrusterFailure, ...] = ()
    end_time: float | None = None
    sensors: SensorsConfig | None = None
    aliases: tuple[str, ...] = ()
    source: Path | None = field(default=None, compare=False)


# --- validation helpers ------------------------------------------------------


_TOP = {
    "name", "aliases", "description", "vehicle", "initial", "attitude_mode", "integrator", "integrator_options", "dt",
    "fixed_pivot",
    "models", "stabiliser", "gimbal_threshold", "wind_W", "wind", "autopilot", "end", "touchdown",
    "sensors",
}


_PRESET_KEYS = {"preset", "thrusters", "disabled", "size", "dry_mass_scale", "inertia_scale", "thrust_scale", "failures"}


def _vehicle(rd: Reader, node: Any) -> tuple[Vehicle, tuple[ThrusterFailure, ...]]:
    """The vehicle and its scheduled thruster failures.

    Preset form: ``{preset: lander, thrusters: canted, disabled: [..], size: L,
    dry_mass_scale: s, inertia_scale: s, thrust_scale: [s0, s1, s2, s3],
    failures: [{thruster: i, time: t}]}``: the scales make the true vehicle differ from the
    nominal preset (robustness sweeps), each > 0.
    """
    if isinstance(node, dict) and "preset" in node:
        v = rd.mapping(node, "vehicle", _PRESET_KEYS)
        rd.choice(v["preset"], "vehicle.preset", tuple(vehicles.PRESETS))
        layout = rd.choice(v.get("thrusters", "standard"), "vehicle.thrusters", vehicles.THRUSTER_LAYOUTS)
        dis = v.get("disabled", [])
        if not isinstance(dis, list):
            raise rd.fail("vehicle.disabled", f"expected a list of thruster indices 0..3, got {dis!r}")
        idx = tuple(rd.integer(i, f"vehicle.disabled[{k}]", 0) for k, i in enumerate(dis))
        for k, i in enumerate(idx):
            if i > 3:
                raise rd.fail(f"vehicle.disabled[{k}]", f"expected a thruster index 0..3, got {i}")
        size = rd.number(v.get("size", c.LANDER_SIZE), "vehicle.size", 0.0, strict_lo=True)
        vehicle = vehicles.PRESETS[v["preset"]](thrusters=layout, disabled=idx, size=size)
        n = vehicle.n_thrusters
        mass_s = rd.number(v.get("dry_mass_scale", 1.0), "vehicle.dry_mass_scale", 0.0, strict_lo=True)
        inertia_s = rd.number(v.get("inertia_scale", 1.0), "vehicle.inertia_scale", 0.0, strict_lo=True)
        thrust_s = None
        if "thrust_scale" in v:
            ts = v["thrust_scale"]
            if not isinstance(ts, list) or len(ts) != n:
                raise rd.fail("vehicle.thrust_scale", f"expected a list of {n} numbers > 0 (one per thruster), got {ts!r}")
            thrust_s = tuple(rd.number(x, f"vehicle.thrust_scale[{i}]", 0.0, strict_lo=True) for i, x in enumerate(ts))
        if mass_s != 1.0 or inertia_s != 1.0 or thrust_s is not None:
            vehicle = vehicles.disperse(vehicle, mass_s, inertia_s, thrust_s)
        return vehicle, _failures(rd, v.get("failures", []), n)
    v = rd.mapping(node, "vehicle", {"preset", "dry_mass", "fuel_capacity", "inertia", "size"}, ("dry_mass", "inertia"))
    inertia = rd.vector3(v["inertia"], "vehicle.inertia")
    for i, x in enumerate(inertia):
        if x <= 0.0:
            raise rd.fail(f"vehicle.inertia[{i}]", f"expected a positive moment of inertia, got {x}")
    return Vehicle(
        dry_mass=rd.number(v["dry_mass"], "vehicle.dry_mass", 0.0, strict_lo=True),
        fuel_capacity=rd.number(v.get("fuel_capacity", 0.0), "vehicle.fuel_capacity", 0.0),
        inertia_diag=inertia,
        size=rd.number(v.get("size", 1.0), "vehicle.size", 0.0, strict_lo=True),
    ), ()


def _failures(rd: Reader, node: Any, n: int) -> tuple[ThrusterFailure, ...]:
    """``vehicle.failures: [{thruster: i, time: t}, ...]``: each thruster at most once, ``0 <= i < n``, ``t >= 0`` s."""
    if not isinstance(node, list):
        raise rd.fail("vehicle.failures", f"expected a list of {{thruster: index, time: seconds}}, got {node!r}")
    out: list[ThrusterFailure] = []
    for k, item in enumerate(node):
        path = f"vehicle.failures[{k}]"
        f = rd.mapping(item, path, {"thruster", "time"}, ("thruster", "time"))
        i = rd.integer(f["thruster"], f"{path}.thruster", 0)
        if i >= n:
            raise rd.fail(f"{path}.thruster", f"expected a thruster index 0..{n - 1}, got {i}")
        if any(o.thruster == i for o in out):
            raise rd.fail(f"{path}.thruster", f"thruster {i} is already listed as failing")
        out.append(ThrusterFailure(i, rd.number(f["time"], f"{path}.time", 0.0)))
    return tuple(out)


def _wind(rd: Reader, top: dict[str, Any]) -> tuple[tuple[float, float, float], GustConfig | None]:
    """Mean wind (``wind_W`` or ``wind.mean_W``, world frame, m/s) and gusts (``wind.gust``)."""
    w = rd.mapping(top.get("wind"), "wind", {"mean_W", "gust"})
    if "mean_W" in w and "wind_W" in top:
        raise rd.fail("wind.mean_W", "the mean wind is given twice: keep wind.mean_W or the older wind_W, not both")
    mean = rd.vector3(w.get("mean_W", top.get("wind_W", [0, 0, 0])), "wind.mean_W" if "mean_W" in w else "wind_W")
    gust = None
    if w.get("gust") is not None:
        g = rd.mapping(w["gust"], "wind.gust", {"sigma", "tau", "seed"}, ("sigma", "tau"))
        sigma = rd.number(g["sigma"], "wind.gust.sigma", 0.0)
        tau = rd.number(g["tau"], "wind.gust.tau", 0.0, strict_lo=True)
        seed = g.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
            raise rd.fail("wind.gust.seed", f"expected an integer in [0, 2**63), got {seed!r}")
        gust = GustConfig(sigma=sigma, tau=tau, seed=seed)
    return mean, gust


def _autopilot(rd: Reader, node: Any) -> AutopilotSection | None:
    """``autopilot: null`` (the sim alone) or ``{controller, parameters, demand_altitude}``."""
    if node is None:
        return None
    if not isinstance(node, dict) or not isinstance(node.get("controller"), str):
        raise rd.fail("autopilot", f"expected null or a mapping with a string 'controller' key, got {node!r}")
    a = rd.mapping(node, "autopilot", set(AUTOPILOT_KEYS))
    params = a.get("parameters") or {}
    if not isinstance(params, dict):
        raise rd.fail("autopilot.parameters", f"expected a mapping (the controller's parameters), got {params!r}")
    demand = a.get("demand_altitude")
    return AutopilotSection(a["controller"], dict(params),
                            None if demand is None else rd.number(demand, "autopilot.demand_altitude", 0.0))


def _on(m: dict[str, Any], key: str) -> bool:
    """A model is on when its key holds a mapping (``{}`` for defaults); absent, null or false is off."""
    return m.get(key) not in (None, False)


def _models(rd: Reader, node: Any) -> Models:
    """``models:`` through the models table: each switched-on section parsed by its own module,
    then each model's needs checked against the others switched on."""
    m = rd.mapping(node, "models", set(MODELS))
    on = {key: entry.parse(rd, m[key], f"models.{key}") for key, entry in MODELS.items() if _on(m, key)}
    for key in on:
        why = MODELS[key].needs(on)
        if why is not None:
            raise rd.fail(f"models.{key}", why)
    return Models(on)


_TOUCHDOWN_KEYS = ("descent_rate", "ground_speed", "tilt_deg")


def _touchdown(rd: Reader, node: Any, models: Models) -> Models:
    """``touchdown: {safe: {descent_rate, ground_speed, tilt_deg}, crash: {...}}`` (m/s, m/s, degrees).

    Missing safe limits default to ``models.ground.safe_speed`` (the original's 1 m/s) and no
    tilt limit (180 deg); missing crash limits to the safe ones. Each crash limit >= its safe one.
    """
    if node is None:
        return models
    ground = models.get("ground")
    if ground is None:
        raise rd.fail("touchdown", "needs the ground: expected models.ground to be switched on")
    t = rd.mapping(node, "touchdown", {"safe", "crash"})
    v = ground.safe_speed
    safe = dict(zip(_TOUCHDOWN_KEYS, (v, v, 180.0)))
    for k, x in rd.mapping(t.get("safe"), "touchdown.safe", set(_TOUCHDOWN_KEYS)).items():
        safe[k] = rd.number(x, f"touchdown.safe.{k}", 0.0, 180.0 if k == "tilt_deg" else None, strict_lo=True)
    crash = dict(safe)
    for k, x in rd.mapping(t.get("crash"), "touchdown.crash", set(_TOUCHDOWN_KEYS)).items():
        crash[k] = rd.number(x, f"touchdown.crash.{k}", safe[k], 180.0 if k == "tilt_deg" else None)
    limits = TouchdownLimits(
        safe["descent_rate"], safe["ground_speed"], math.radians(safe["tilt_deg"]),
        crash["descent_rate"], crash["ground_speed"], math.radians(crash["tilt_deg"]),
    )
    from dataclasses import replace

    return models.with_config("ground", replace(ground, limits=limits))


def _initial(rd: Reader, node: Any, vehicle: Vehicle, mode: str) -> np.ndarray:
    i = rd.mapping(node, "initial", {"position_W", "velocity_W", "attitude", "omega_B", "fuel"})
    r = rd.vector(i.get("position_W", [0, 0, 0]), "initial.position_W")
    v = rd.vector(i.get("velocity_W", [0, 0, 0]), "initial.velocity_W")
    w = rd.vector(i.get("omega_B", [0, 0, 0]), "initial.omega_B")
    fuel = rd.number(i.get("fuel", vehicle.fuel_capacity), "initial.fuel", 0.0, vehicle.fuel_capacity)
    att = rd.mapping(i.get("attitude", {"quaternion": [1, 0, 0, 0]}), "initial.attitude", {"quaternion", "euler_deg"})
    if len(att) != 1:
        raise rd.fail("initial.attitude", "expected exactly one of quaternion (s, x, y, z) or euler_deg (ZXZ, degrees)")
    if "quaternion" in att:
        q = np.array(rd.vector(att["quaternion"], "initial.attitude.quaternion", 4))
        if np.linalg.norm(q) == 0.0:
            raise rd.fail("initial.attitude.quaternion", "expected a non-zero quaternion")
        q = rotation.quat_normalise(q)
        a = q if mode == "quaternion" else rotation.quat_to_euler(q)
    else:
        E = np.radians(rd.vector(att["euler_deg"], "initial.attitude.euler_deg"))
        a = E if mode == "euler" else rotation.euler_to_quat(E)
    return pack(np.array(r), np.array(v), a, np.array(w), fuel)


def _integrator_options(rd: Reader, integ: str, node: Any) -> dict[str, Any]:
    """``integrator_options``: keyword options of the chosen method (e.g. ``rtol``/``atol`` of ``adaptive``)."""
    from lander_sim.integrators import make, options_of

    allowed = set(options_of(integ))
    opts = rd.mapping(node, "integrator_options", allowed)
    try:
        make(integ, **opts)  # the integrator validates values (e.g. positive tolerances)
    except ValueError as exc:
        raise rd.fail("integrator_options", str(exc)) from None
    return dict(opts)


def parse_scene(data: Any, file: str, source: Path | None = None) -> Scene:
    """Validate already-parsed YAML ``data``; ``file`` names it in errors."""
    rd = Reader(file, SceneError)
    top = rd.mapping(data, "", _TOP, ("vehicle", "initial", "dt"))
    name = rd.string(top.get("name", Path(file).stem), "name")
    aliases_node = top.get("aliases", [])
    if not isinstance(aliases_node, list):
        raise rd.fail("aliases", f"expected a list of strings, got {aliases_node!r}")
    aliases = tuple(str(rd.string(a, f"aliases[{k}]")) for k, a in enumerate(aliases_node))
    mode: AttitudeMode = "euler" if rd.choice(top.get("attitude_mode", "quaternion"), "attitude_mode",
                                               ("quaternion", "euler")) == "euler" else "quaternion"
    integ = rd.choice(top.get("integrator", "verlet"), "integrator", tuple(sorted(INTEGRATORS)))
    integ_options = _integrator_options(rd, integ, top.get("integrator_options"))
    vehicle, failures = _vehicle(rd, top["vehicle"])
    models = _touchdown(rd, top.get("touchdown"), _models(rd, top.get("models")))
    if "thrusters" in models and vehicle.n_thrusters == 0:
        raise rd.fail("models.thrusters", "the vehicle has no thrusters: use vehicle.preset: lander")
    autopilot = _autopilot(rd, top.get("autopilot"))
    dt = rd.number(top["dt"], "dt", 0.0, strict_lo=True)
    mean_wind, gust = _wind(rd, top)
    end = rd.mapping(top.get("end"), "end", {"max_time"})
    end_time = rd.number(end["max_time"], "end.max_time", 0.0, strict_lo=True) if "max_time" in end else None
    return Scene(
        name=name,
        description=rd.string(top.get("description", ""), "description"),
        vehicle=vehicle,
        initial_state=_initial(rd, top["initial"], vehicle, mode),
        attitude=mode,
        integrator=integ,
        integrator_options=integ_options,
        dt=dt,
        models=models,
        translation=not rd.boolean(top.get("fixed_pivot", False), "fixed_pivot"),
        stabiliser=rd.boolean(top.get("stabiliser", False), "stabiliser"),
        autopilot=autopilot,
        gimbal_threshold=rd.number(top.get("gimbal_threshold", 1e-3), "gimbal_threshold", 0.0, 1.0, strict_lo=True),
        wind_W=mean_wind,
        gust=gust,
        thruster_failures=failures,
        end_time=end_time,
        sensors=parse_sensors(rd, top.get("sensors")),
        aliases=aliases,
        source=source,
    )


def load_file(path: str | Path) -> Scene:
    """Load and validate one scene file."""
    p = Path(path)
    return parse_scene(read_yaml(p, "scene file", SceneError), p.name, p)


def _packaged() -> list[Path]:
    return sorted(SCENE_DIR.glob("*.yaml"))


def list_scenes() -> list[SceneInfo]:
    """The packaged scenes, sorted by name."""
    infos = []
    for p in _packaged():
        data = yaml.safe_load(p.read_text()) or {}
        infos.append(
            SceneInfo(
                name=str(data.get("name", p.stem)),
                aliases=tuple(str(a) for a in data.get("aliases", []) or []),
                description=str(data.get("description", "")),
                path=p,
            )
        )
    return sorted(infos, key=lambda i: i.name)


def load_scene(name_or_path: str | Path) -> Scene:
    """A packaged scene by name or alias (``"hover"``, ``"7"``), or a YAML file by path."""
    s = str(name_or_path)
    if s.endswith((".yaml", ".yml")) or Path(s).is_file():
        return load_file(s)
    for info in list_scenes():
        if s == info.name or s in info.aliases:
            return load_file(info.path)
    names = ", ".join(f"{i.name}" + (f" ({'/'.join(i.aliases)})" if i.aliases else "") for i in list_scenes())
    raise SceneError(f"unknown scene {s!r}; choose one of: {names}")
