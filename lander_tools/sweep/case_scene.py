"""One dispersed case as a *scene*: the nominal scene file's data with the case written into it.

Both paths fly exactly this scene, so they fly the same equations with the same inputs: the
core-only path parses it (:func:`flown_scene`), the through-ROS path writes it to a YAML file for
the simulator node (:mod:`lander_tools.sweep.ros_path`). What the case changes:

* ``initial``: first the orbit (:func:`orbit_start`): ``orbit_altitude`` scales the initial orbit
  about the planet's centre to the new radius, ``orbit_phase`` rotates position and velocity about
  the orbit normal; then tilt ``q' = q x p`` with ``p`` the rotation by ``tilt`` about a horizontal
  *body* axis (eq 10: a right-multiplied quaternion rotates in the body frame under the
  world-to-body convention); altitude offset along ``r_hat``; world-frame velocity and body-rate
  offsets. The attitude is not turned with the orbit phase: it stays the scene's in the world frame.
* ``vehicle``: ``dry_mass_scale = 1 + mass_error``, ``inertia_scale = 1 + inertia_error``,
  ``thrust_scale[i] = 1 + thrust_error[i]``, ``failures: [{thruster, time}]``
  (:func:`lander_sim.scenes.vehicles.disperse`, failures handled by the Simulation).
* ``wind``: ``mean_W`` = the scene's mean + the case's; ``gust`` = ``{sigma: wind_gust,
  tau: end.gust_time_constant, seed}`` with the seed drawn from the flight's own stream
  (:func:`gust_seed`), so the gusts are a function of ``(master seed, index)`` alone.
* ``models.atmosphere.surface_density`` = the scene's times ``1 + density_error``.
* ``sensors.seed`` (a scene with sensors) = :func:`sensor_seed`, from the flight's own stream: each
  flight's sensor noise, switch-on biases and initial estimation error are its own; every sensor's
  noise parameters times ``1 + sensor_noise_error`` and its bias and bias-walk parameters times
  ``1 + sensor_bias_error`` (:data:`SENSOR_NOISE`, :data:`SENSOR_BIAS`). The navigation filter keeps
  the nominal scene's IMU model (what the designer believes), as the controller its vehicle.
* thruster directions tilted by ``thruster_cant`` (:func:`canted_directions`): **no scene key
  carries them yet**, so :func:`flown_scene` applies them to the parsed scene's vehicle and
  :func:`write_case_scene` (the through-ROS path) refuses such a case (:class:`NotRepresentable`).

The controller is designed on the *nominal* scene's vehicle and models (what the designer believes):
its atmosphere is the nominal one whatever the flown density.
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
from lander_tools.sweep.dispersion import FlightCase, gust_stream, stream
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


def scene_data(spec: SweepSpec) -> dict[str, Any]:
    """The sweep's scene file as parsed YAML (cached per scene), into which a flight's case is written.

    Raises :class:`NotRepresentable` when the scene was not loaded from a file."""
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


#: The noise parameters (``sensor_noise_error``) and the bias and bias-walk parameters
#: (``sensor_bias_error``) of each sensor (lander_sim.sensors' parameter tables).
SENSOR_NOISE = {"imu": ("gyro_noise_density", "accel_noise_density"), "star_tracker": ("noise",),
                "altimeter": ("noise_floor", "noise_fraction"), "doppler": ("noise_floor", "noise_fraction"),
                "ground_fix": ("position_noise", "velocity_noise")}
SENSOR_BIAS = {"imu": ("gyro_bias", "accel_bias", "gyro_bias_walk", "accel_bias_walk"), "star_tracker": ("bias",),
               "altimeter": ("bias",), "doppler": ("bias",)}


def sensor_seed(case: FlightCase) -> int:
    """Seed of the flight's sensors (``sensors.seed``: every noise and switch-on bias draw, and the
    filter's initial error), in [0, 2**63), from its own stream: the sensors' errors differ from
    flight to flight and never shift the case's other draws."""
    return int(stream(case.seed, case.index, "sensors").integers(0, 2**63 - 1))


def _rotate(x: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``x`` rotated by ``angle`` [rad] about the unit vector ``axis`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return x * c + np.cross(axis, x) * s + axis * float(axis @ x) * (1.0 - c)


def orbit_start(r_W: np.ndarray, v_W: np.ndarray, orbit_altitude: float, orbit_phase: float) -> tuple[np.ndarray, np.ndarray]:
    """The initial position [m] and velocity [m/s] (world frame) moved to another orbit and phase.

    ``orbit_altitude`` [m]: the position moves along ``r_hat`` to the radius ``r' = r + orbit_altitude``
    and the velocity is scaled by ``sqrt(r / r')``. That is the start's whole orbit scaled about the
    planet's centre by ``k = r' / r`` (a Kepler orbit scaled by ``k`` has its speeds scaled by
    ``1/sqrt(k)``): same eccentricity, orientation and flight-path angle, semi-major axis times ``k``.
    For the shipped circular orbits this is the circular speed ``sqrt(GM / r')`` at the new radius
    (vis-viva, exactly to rounding); a non-circular start keeps its shape, with the periapsis and the
    apoapsis both scaled by ``k``. A start at rest stays at rest (the new altitude alone).

    ``orbit_phase`` [rad]: position and velocity rotated by the angle about the orbit normal
    ``r x v`` (the lander further along its orbit, or behind it); ``|r|``, ``|v|`` and the orbit plane
    are kept. Needs ``r x v != 0``.

    Raises ``NotRepresentable`` (a ``ValueError``) naming the dispersion when the start has no such
    orbit: at the planet's centre, a radius that would not stay positive, no orbit plane.
    """
    r, v = np.array(r_W, dtype=float), np.array(v_W, dtype=float)
    if orbit_altitude:
        rn = float(np.linalg.norm(r))
        if rn == 0.0 or rn + orbit_altitude <= 0.0:
            raise NotRepresentable(f"dispersions.orbit_altitude: cannot move a start at radius {rn} m by {orbit_altitude} m")
        r = r + orbit_altitude * r / rn
        v = v * math.sqrt(rn / float(np.linalg.norm(r)))
    if orbit_phase:
        n = np.cross(r, v)
        nn = float(np.linalg.norm(n))
        if nn == 0.0:
            raise NotRepresentable("dispersions.orbit_phase: the scene's start has r x v = 0 (at rest or moving radially): "
                                   "no orbit plane to rotate in")
        axis = n / nn
        r, v = _rotate(r, axis, orbit_phase), _rotate(v, axis, orbit_phase)
    return r, v


def _perpendicular_axes(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vector ``d`` to a right-handed orthonormal frame
    ``(u1, u2, d)``; ``u1`` is ``d x e_k`` normalised, ``e_k`` the body axis least aligned with ``d``."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(d)))] = 1.0
    u1 = np.cross(d, e)
    u1 /= float(np.linalg.norm(u1))
    return u1, np.cross(d, u1)


def canted_directions(directions: Any, cant: tuple[float, ...], azimuth: tuple[float, ...]) -> list[np.ndarray]:
    """Each thruster's unit direction ``d_i`` tilted by ``cant[i]`` [rad] about the axis perpendicular to
    it at ``azimuth[i]`` [rad] (``a = cos(az) u1 + sin(az) u2``, :func:`_perpendicular_axes`):
    ``d' = d cos(cant) + (a x d) sin(cant)``, re-normalised (unit to rounding already). A drawn azimuth
    uniform in [0, 2 pi) makes the axis uniform among those perpendicular to ``d``; a negative cant
    tilts the other way about the same axis."""
    out = []
    for d, angle, az in zip(directions, cant, azimuth):
        d = np.asarray(d, dtype=float)
        u1, u2 = _perpendicular_axes(d)
        a = math.cos(az) * u1 + math.sin(az) * u2
        t = d * math.cos(angle) + np.cross(a, d) * math.sin(angle)
        out.append(t / float(np.linalg.norm(t)))
    return out


def dispersed_initial_state(scene: Any, case: FlightCase) -> np.ndarray:
    """The nominal initial state with the case's orbit and offsets (see the module docstring)."""
    y = np.array(scene.initial_state, dtype=float)
    if case.orbit_altitude or case.orbit_phase:
        y[R_W], y[V_W] = orbit_start(y[R_W], y[V_W], case.orbit_altitude, case.orbit_phase)
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
    data = scene_data(spec)
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
    if isinstance(data.get("sensors"), dict):
        data["sensors"] = {**data["sensors"], "seed": sensor_seed(case)}
    for name, error, table in (("sensor_noise_error", case.sensor_noise_error, SENSOR_NOISE),
                               ("sensor_bias_error", case.sensor_bias_error, SENSOR_BIAS)):
        if error:
            if scene.sensors is None:
                raise NotRepresentable(f"dispersions.{name}: scene {scene.name!r} has no sensors")
            for key, values in scene.sensors.sections.items():
                section = dict(data["sensors"].get(key) or {})
                for param in table.get(key, ()):
                    section[param] = float(values[param]) * (1.0 + error)
                data["sensors"][key] = section
    if case.density_error:
        atmosphere = scene.models.get("atmosphere")
        if atmosphere is None:
            raise NotRepresentable(f"dispersions.density_error: scene {scene.name!r} has no atmosphere (models.atmosphere)")
        models = data["models"]
        models["atmosphere"] = {**(models.get("atmosphere") or {}),
                                "surface_density": float(atmosphere.surface_density * (1.0 + case.density_error))}
    return data


def flown_scene(spec: SweepSpec, case: FlightCase) -> Any:
    """The :class:`~lander_sim.scenes.Scene` flight ``case`` flies (core-only path): the case's scene
    data parsed, then the thruster cant applied to its vehicle (no scene key carries it yet)."""
    import dataclasses

    from lander_sim.scenes import parse_scene

    data = case_scene_data(spec, case)
    scene = parse_scene(data, f"{data['name']}.yaml", nominal_scene(spec).source)
    if case.thruster_cant:
        th = scene.vehicle.thrusters
        if len(th) != len(case.thruster_cant):
            raise NotRepresentable(f"dispersions.thruster_cant_error: {len(case.thruster_cant)} cant angles for "
                                   f"{len(th)} thrusters")
        dirs = canted_directions([t.direction_B for t in th], case.thruster_cant, case.thruster_cant_azimuth)
        vehicle = dataclasses.replace(scene.vehicle, thrusters=tuple(
            dataclasses.replace(t, direction_B=d) for t, d in zip(th, dirs)))
        scene = dataclasses.replace(scene, vehicle=vehicle)
    return scene


def write_case_scene(spec: SweepSpec, case: FlightCase, folder: Path) -> Path:
    """Write the case's scene as ``folder/<name>.yaml`` (through-ROS path); return its path.
    A case with a thruster cant cannot be written (no scene key for it): ``NotRepresentable``."""
    if any(case.thruster_cant):
        raise NotRepresentable("dispersions.thruster_cant_error: no scene key carries a thruster's direction yet, "
                               "so the through-ROS path cannot fly this case (core-only flies it)")
    data = case_scene_data(spec, case)
    path = Path(folder) / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
