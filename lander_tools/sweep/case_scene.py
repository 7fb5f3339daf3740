"""One dispersed case as a *scene*: the nominal scene file's data with the case written into it.

Both paths fly exactly this scene, so they fly the same equations with the same inputs: the
core-only path parses it (:func:`flown_scene`), the through-ROS path writes it to a YAML file for
the simulator node (:mod:`lander_tools.sweep.ros_path`). What the case changes:

* ``initial``: tilt ``q' = q x p`` with ``p`` the rotation by ``tilt`` about a horizontal *body*
  axis (eq 10: a right-multiplied quaternion rotates in the body frame under the world-to-body
  convention); altitude offset along ``r_hat``; world-frame velocity and body-rate offsets.
* ``vehicle``: ``dry_mass_scale = 1 + mass_error``, ``inertia_scale = 1 + inertia_error``,
  ``thrust_scale[i] = 1 + thrust_error[i]``, ``failures: [{thruster, time}]``
  (:func:`lander_sim.scenes.vehicles.disperse`, failures handled by the Simulation).
* ``wind``: ``mean_W`` = the scene's mean + the case's; ``gust`` = ``{sigma: wind_gust,
  tau: end.gust_time_constant, seed}`` with the seed drawn from the flight's own stream
  (:func:`gust_seed`), so the gusts are a function of ``(master seed, index)`` alone.

The controller is designed on the *nominal* scene's vehicle (what the designer believes).
"""
from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lander_sim.physics import rotation
from lander_sim.physics.state import ATT, EULER, FUEL, OMEGA_B, R_W, V_W
from lander_tools.sweep.dispersion import FlightCase, gust_stream
from lander_tools.sweep.spec import SweepSpec

# Per-process caches of the nominal scene and its raw YAML (identical for every flight of a sweep).
_SCENES: dict[str, Any] = {}
_RAW: dict[str, dict[str, Any]] = {}


class NotRepresentable(ValueError):
    """The nominal scene cannot carry a case (e.g. not loaded from a file, or a custom vehicle)."""


def nominal_scene(spec: SweepSpec) -> Any:
    """The undispersed scene (cached per process)."""
    scene = _SCENES.get(spec.scene)
    if scene is None:
        from lander_sim.scenes import load_scene

        scene = _SCENES[spec.scene] = load_scene(spec.scene)
    return scene


def clear_caches() -> None:
    """Forget cached scenes (a replay "from scratch")."""
    _SCENES.clear()
    _RAW.clear()


def _raw(spec: SweepSpec) -> dict[str, Any]:
    scene = nominal_scene(spec)
    data = _RAW.get(spec.scene)
    if data is None:
        if scene.source is None:
            raise NotRepresentable(f"scene {scene.name!r} was not loaded from a file, so a case cannot be written into it")
        data = _RAW[spec.scene] = yaml.safe_load(Path(scene.source).read_text())
        if not isinstance(data.get("vehicle"), dict) or "preset" not in data["vehicle"]:
            raise NotRepresentable(f"scene {scene.name!r}: vehicle dispersions need a preset vehicle (vehicle: {{preset: ...}})")
    return copy.deepcopy(data)


def gust_seed(case: FlightCase) -> int:
    """Seed of the flight's gust process, in [0, 2**63) (a ROS int64 parameter can carry it)."""
    return int(gust_stream(case).integers(0, 2**63 - 1))


def dispersed_initial_state(scene: Any, case: FlightCase) -> np.ndarray:
    """The nominal initial state with the case's offsets (see the module docstring)."""
    y = np.array(scene.initial_state, dtype=float)
    r = y[R_W]
    rn = float(np.linalg.norm(r))
    if case.altitude_offset and rn > 0.0:
        y[R_W] = r + case.altitude_offset * r / rn
    y[V_W] += case.velocity_W
    y[OMEGA_B] += case.body_rate_B
    if case.tilt:
        p = rotation.axis_angle_to_quat(np.array([math.cos(case.tilt_azimuth), math.sin(case.tilt_azimuth), 0.0]), case.tilt)
        if scene.attitude == "quaternion":
            y[ATT] = rotation.quat_mult(y[ATT], p)
        else:
            y[EULER] = rotation.quat_to_euler(rotation.quat_mult(rotation.euler_to_quat(y[EULER]), p))
    return y


def case_scene_data(spec: SweepSpec, case: FlightCase) -> dict[str, Any]:
    """The scene (YAML-shaped data) flight ``case`` flies; floats round-trip exactly through YAML."""
    scene = nominal_scene(spec)
    data = _raw(spec)
    data["name"] = f"{scene.name}-sweep-{spec.seed}-{case.index}"
    data["aliases"] = []
    y = dispersed_initial_state(scene, case)
    q = y[ATT] if scene.attitude == "quaternion" else rotation.euler_to_quat(y[EULER])
    data["initial"] = {
        "position_W": [float(x) for x in y[R_W]],
        "velocity_W": [float(x) for x in y[V_W]],
        "attitude": {"quaternion": [float(x) for x in q]},
        "omega_B": [float(x) for x in y[OMEGA_B]],
        "fuel": float(y[FUEL]),
    }
    v = data["vehicle"]
    if case.mass_error:
        v["dry_mass_scale"] = 1.0 + case.mass_error
    if case.inertia_error:
        v["inertia_scale"] = 1.0 + case.inertia_error
    if any(case.thrust_error):
        v["thrust_scale"] = [1.0 + e for e in case.thrust_error]
    if case.failed_thruster >= 0:
        v["failures"] = list(v.get("failures", [])) + [{"thruster": case.failed_thruster, "time": case.failure_time}]
    wind = dict(data.get("wind") or {})
    data.pop("wind_W", None)
    wind["mean_W"] = [float(a + b) for a, b in zip(scene.wind_W, case.wind_mean_W)]
    if case.wind_gust:
        wind["gust"] = {"sigma": case.wind_gust, "tau": spec.end.gust_time_constant, "seed": gust_seed(case)}
    data["wind"] = wind
    return data


def flown_scene(spec: SweepSpec, case: FlightCase) -> Any:
    """The :class:`~lander_sim.scenes.Scene` flight ``case`` flies (core-only path)."""
    from lander_sim.scenes import parse_scene

    data = case_scene_data(spec, case)
    return parse_scene(data, f"{data['name']}.yaml", nominal_scene(spec).source)


def write_case_scene(spec: SweepSpec, case: FlightCase, folder: Path) -> Path:
    """Write the case's scene as ``folder/<name>.yaml`` (through-ROS path); return its path."""
    data = case_scene_data(spec, case)
    path = Path(folder) / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
