"""Which figures of a flight apply, from what its scene has (no rclpy).

``lander analyse`` (:mod:`lander_tools.analysis`) and the flight summary of ``lander fly`` report a
figure only where the scene can produce it, and "n/a" where it cannot; this module is the one
place those rules live:

* **altitude** applies to a body that flies about the planet: not to a fixed pivot (the seed-1
  rotor and pendulum scenes sit at ``r_W = 0``, the planet's centre, with no local vertical);
* **the figures of flight over a surface** (altitude, climb rate, ground speed, tilt from the
  local vertical, and the hover's step response) apply where the scene has a ground to fly over
  (its ``ground`` model): in free space (scenario 8, 1000 R out, gravity only) the altitude is
  a radius, "upright" is the attitude law's own frame, not the local vertical, and no law holds
  an altitude;
* **fuel** applies to a vehicle with thrusters (a rotor has none: its tank reads 0 kg, which is
  no measurement);
* **the z-axis track** (reference 1, Figure 1) applies to a fixed pivot, the gimballed rotor's
  mount, known from the scene's ``fixed_pivot`` (never from a file's name);
* **angular-momentum drift** applies only where ``L_W`` is conserved, i.e. no external torque
  about the centre of mass (dynamics reference eq 2): no thrust, no stabiliser, no parachute, no
  ground contact, and none of the scene's models that torque on their own (a constant force off
  the centre of mass, mesh drag);
* **gimbal-lock events** are the simulator's ``GIMBAL_LOCK`` events, one each time the integrated
  ZXZ angles enter ``|sin theta| < gimbal_threshold`` (reference 1, section 3.2). Only a scene
  integrated in Euler angles has them: in quaternion mode the angles are only derived for display,
  and the flag the state carries near ``theta = 0`` is no event;
* **the estimate's figures** (errors with their 3-sigma bounds, NEES: :mod:`lander_tools.estimate_analysis`)
  apply to a bag that recorded the estimator node's ``/lander/estimate/odometry`` beside the truth
  (a flight flown with ``lander fly --estimate``); **NIS** applies to no bag: it needs each update's
  innovation and its covariance, which no topic carries.
"""
from __future__ import annotations

import functools
from collections.abc import Container, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

#: ``FlightEvent.GIMBAL_LOCK`` (lander_interfaces/msg/FlightEvent.msg), as a plain int.
GIMBAL_LOCK_KIND = 2
#: The estimator node's estimate with its covariance (``nav_msgs/Odometry``, docs/estimation.md).
ESTIMATE_TOPIC = "/lander/estimate/odometry"


@dataclass(frozen=True)
class SceneFacts:
    """What a flight's scene has, as far as the figures of a flight depend on it."""

    name: str
    fixed_pivot: bool  #: rotation only, about the pivot (scene key ``fixed_pivot``)
    attitude: str  #: ``euler`` or ``quaternion`` (the integrated attitude)
    n_thrusters: int
    #: A ground to fly over (scene model ``ground``), and a body free to move: altitude, climb
    #: rate, ground speed, tilt and the hover's figures apply.
    surface: bool
    #: Models that put a torque on the body whatever the state's flags say (names, for messages).
    torque_models: tuple[str, ...]


def scene_facts(meta: Mapping[str, str]) -> SceneFacts | None:
    """The facts of the scene a bag's metadata names (``scene``: a name, an alias or a YAML
    path); ``None`` if it names none or the scene cannot be loaded (renamed, file moved)."""
    name = meta.get("scene")
    return _facts_of(name) if name else None


@functools.lru_cache(maxsize=32)
def _facts_of(name: str) -> SceneFacts | None:
    try:
        from lander_sim.scenes import load_scene

        scene = load_scene(name)
    except Exception:  # noqa: BLE001 - any failure to load: the scene is unknown here
        return None
    torques = []
    cf = scene.models.get("constant_force")
    if cf is not None and any(cf.point_B) and any(cf.force_W):  # torque point_B x (R F_W)
        torques.append("constant_force")
    drag = scene.models.get("drag")
    if drag is not None and getattr(drag, "kind", "") == "mesh":
        torques.append("mesh drag")
    return SceneFacts(name=scene.name, fixed_pivot=not scene.translation, attitude=str(scene.attitude),
                      n_thrusters=scene.vehicle.n_thrusters, torque_models=tuple(torques),
                      surface=bool(scene.translation) and "ground" in scene.models)


def altitude_applies(r_W: np.ndarray, facts: SceneFacts | None = None) -> bool:
    """Altitude is a figure of this state: not at the planet's centre (a fixed pivot's ``r_W = 0``),
    and, by the scene, a body that flies over a surface (:attr:`SceneFacts.surface`)."""
    return not (facts is not None and not facts.surface) and float(np.dot(r_W, r_W)) > 0.0


def fuel_applies(n_thrusters: int) -> bool:
    """Fuel is a figure of a vehicle with thrusters (``n_thrusters``: the scene's, or the length
    of the state's ``throttles``, which has one entry per thruster)."""
    return n_thrusters > 0


def estimate_applies(topics: Container[str]) -> bool:
    """The estimate's figures apply: ``topics`` (a :class:`~lander_tools.bagio.Bag`, or names of
    the topics with messages) holds :data:`ESTIMATE_TOPIC`."""
    return ESTIMATE_TOPIC in topics


def gimbal_lock_count(event_kinds: Iterable[int]) -> int:
    """Gimbal-lock events of a flight: the number of ``GIMBAL_LOCK`` events among its events'
    kinds (``lander fly`` counts the same events as they arrive)."""
    return sum(1 for k in event_kinds if int(k) == GIMBAL_LOCK_KIND)


def gimbal_lock_entries(flags: np.ndarray, attitude: str) -> int:
    """The same count from the states' ``gimbal_lock`` flags, for a bag without its events: the
    entries into the near-lock region (the simulator's rule: a start inside counts), in Euler mode
    only; 0 in quaternion mode, where nothing is integrated in the angles."""
    if attitude != "euler" or not len(flags):
        return 0
    f = np.asarray(flags, dtype=bool)
    return int(f[0]) + int(np.sum(f[1:] & ~f[:-1]))


def torque_free(throttles: np.ndarray, stabiliser: np.ndarray, parachute: np.ndarray, phase: np.ndarray,
                facts: SceneFacts | None) -> np.ndarray:
    """(N,) True at the states where no external torque acts (module docstring): every throttle
    zero, stabiliser off, parachute stowed, flying (no ground contact), and a scene known to have
    no model that torques on its own. All False when the scene is unknown (conservation cannot be
    told) or has such a model."""
    n = len(phase)
    if facts is None or facts.torque_models:
        return np.zeros(n, dtype=bool)
    thr = np.asarray(throttles, dtype=float).reshape(n, -1)
    return (np.all(np.nan_to_num(thr) == 0.0, axis=1) & ~np.asarray(stabiliser, bool) & ~np.asarray(parachute, bool)
            & (np.asarray(phase) == 0))
