"""Seeded sampling of one flight's dispersed parameters from ``(master seed, flight index)`` alone.

Each dispersed quantity has its own random stream ``default_rng([seed, index, crc32(name)])``
(numpy's ``SeedSequence`` hashes the whole key), so

* flight ``i`` is drawn identically whether it is flown in a sweep of 10 or 10,000 flights, in any
  order, on any worker, or alone (``lander sweep SPEC --replay i``);
* switching one dispersion on or off does not change the draws of the others;
* every controller of a comparison sees the very same case (the controller is not in the key).

crc32 is used rather than ``hash()`` because Python salts string hashes per process.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from lander_tools.sweep.spec import Distribution, SweepSpec

#: Relative errors are clipped here so a mass, inertia or thrust always stays positive.
_MIN_RELATIVE = -0.99


def stream(seed: int, index: int, name: str) -> np.random.Generator:
    """The random stream of quantity ``name`` for flight ``index`` of master ``seed``."""
    return np.random.default_rng([seed, index, zlib.crc32(name.encode())])


@dataclass(frozen=True)
class FlightCase:
    """The dispersed parameters of one flight (zeros when a dispersion is off).

    Attributes
    ----------
    index, seed : int
        Flight index and master seed: together they determine everything below.
    tilt : float
        Initial attitude error: rotation angle [rad] about the horizontal body axis at azimuth
        ``tilt_azimuth`` [rad] from body x, in the body x-y plane.
    body_rate_B : tuple of 3 float
        Added to the initial angular velocity, body frame [rad/s].
    altitude_offset : float
        Added to the initial altitude along the local vertical [m].
    velocity_W : tuple of 3 float
        Added to the initial velocity, world frame [m/s].
    wind_mean_W : tuple of 3 float
        Steady wind, world frame [m/s].
    wind_gust : float
        Gust standard deviation per world axis [m/s] (Gauss-Markov process, seeded by the case).
    demand_step : float
        Step in the demand altitude at ``end.demand_step_time`` [m].
    mass_error, inertia_error : float
        Relative errors of the true dry mass and inertia vs the controller's model.
    thrust_error : tuple of float
        Relative error of each thruster's maximum thrust.
    failed_thruster : int
        Index of the thruster that fails, or -1 for none.
    failure_time : float
        When it fails [s] (NaN for none).
    orbit_altitude : float
        Change of the initial orbit's radius [m] (:func:`~.case_scene.dispersed_initial_state`).
    orbit_phase : float
        Rotation of the initial position and velocity about the orbit normal ``r x v`` [rad].
    density_error : float
        Relative error of the flown atmosphere's surface density.
    thruster_cant : tuple of float
        Tilt of each thruster's direction [rad] ...
    thruster_cant_azimuth : tuple of float
        ... about the axis perpendicular to it at this azimuth [rad]
        (:func:`~.case_scene.canted_directions`); empty when the dispersion is off.
    sensor_noise_error, sensor_bias_error : float
        Relative errors of every sensor's noise parameters, and of its bias and bias-walk
        parameters, vs the scene's (:func:`~.case_scene.case_scene_data`).
    """

    index: int
    seed: int
    tilt: float = 0.0
    tilt_azimuth: float = 0.0
    body_rate_B: tuple[float, float, float] = (0.0, 0.0, 0.0)
    altitude_offset: float = 0.0
    velocity_W: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_mean_W: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_gust: float = 0.0
    demand_step: float = 0.0
    mass_error: float = 0.0
    inertia_error: float = 0.0
    thrust_error: tuple[float, ...] = ()
    failed_thruster: int = -1
    failure_time: float = math.nan
    orbit_altitude: float = 0.0
    orbit_phase: float = 0.0
    density_error: float = 0.0
    thruster_cant: tuple[float, ...] = ()
    thruster_cant_azimuth: tuple[float, ...] = ()
    sensor_noise_error: float = 0.0
    sensor_bias_error: float = 0.0

    def parameters(self) -> dict[str, float]:
        """Scalar summary of the case for tables and scatter plots (vectors as magnitudes)."""
        return {
            "tilt": self.tilt,
            "body_rate": float(np.linalg.norm(self.body_rate_B)),
            "altitude_offset": self.altitude_offset,
            "velocity_offset": float(np.linalg.norm(self.velocity_W)),
            "wind_mean": float(np.linalg.norm(self.wind_mean_W)),
            "wind_gust": self.wind_gust,
            "demand_step": self.demand_step,
            "mass_error": self.mass_error,
            "inertia_error": self.inertia_error,
            "thrust_error_max": max((abs(e) for e in self.thrust_error), default=0.0),
            "failed_thruster": float(self.failed_thruster),
            "failure_time": self.failure_time,
            "orbit_altitude": self.orbit_altitude,
            "orbit_phase": self.orbit_phase,
            "density_error": self.density_error,
            "thruster_cant_max": max((abs(a) for a in self.thruster_cant), default=0.0),
            "sensor_noise_error": self.sensor_noise_error,
            "sensor_bias_error": self.sensor_bias_error,
        }

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


#: The columns of :meth:`FlightCase.parameters`, in order.
PARAMETER_COLUMNS = tuple(FlightCase(0, 0).parameters())


def _draw(spec: SweepSpec, index: int, name: str, dist: Distribution | None, size: int | None = None) -> Any:
    if dist is None:
        return 0.0 if size is None else np.zeros(size)
    return dist.sample(stream(spec.seed, index, name), size)


def _vec3(x: np.ndarray | float) -> tuple[float, float, float]:
    a = np.broadcast_to(np.asarray(x, dtype=float), (3,))
    return (float(a[0]), float(a[1]), float(a[2]))


def draw_case(spec: SweepSpec, index: int, n_thrusters: int) -> FlightCase:
    """Draw flight ``index``'s case; depends only on ``(spec.seed, index)`` and the dispersion settings."""
    d = spec.dispersions
    tilt = float(_draw(spec, index, "initial_tilt", d.initial_tilt))
    azimuth = float(stream(spec.seed, index, "tilt_azimuth").uniform(0.0, 2.0 * math.pi)) if d.initial_tilt else 0.0
    thrust = np.maximum(_draw(spec, index, "thrust_error", d.thrust_error, n_thrusters), _MIN_RELATIVE)
    failed, t_fail = -1, math.nan
    if d.thruster_failure is not None and n_thrusters > 0:
        rng = stream(spec.seed, index, "thruster_failure")
        # Always draw all three numbers so the stream does not depend on the outcome.
        u, which = rng.uniform(), int(rng.integers(n_thrusters))
        when = max(0.0, float(d.thruster_failure.time.sample(rng)))
        if u < d.thruster_failure.probability:
            failed, t_fail = which, when
    cant: tuple[float, ...] = ()
    cant_azimuth: tuple[float, ...] = ()
    if d.thruster_cant_error is not None and n_thrusters > 0:
        cant = tuple(float(a) for a in _draw(spec, index, "thruster_cant_error", d.thruster_cant_error, n_thrusters))
        azimuth_rng = stream(spec.seed, index, "thruster_cant_azimuth")
        cant_azimuth = tuple(float(a) for a in azimuth_rng.uniform(0.0, 2.0 * math.pi, n_thrusters))
    return FlightCase(
        index=index,
        seed=spec.seed,
        tilt=tilt,
        tilt_azimuth=azimuth,
        body_rate_B=_vec3(_draw(spec, index, "initial_body_rate", d.initial_body_rate, 3)),
        altitude_offset=float(_draw(spec, index, "initial_altitude", d.initial_altitude)),
        velocity_W=_vec3(_draw(spec, index, "initial_velocity", d.initial_velocity, 3)),
        wind_mean_W=_vec3(_draw(spec, index, "wind_mean", d.wind_mean, 3)),
        wind_gust=float(_draw(spec, index, "wind_gust", d.wind_gust)),
        demand_step=float(_draw(spec, index, "demand_altitude_step", d.demand_altitude_step)),
        mass_error=max(float(_draw(spec, index, "mass_error", d.mass_error)), _MIN_RELATIVE),
        inertia_error=max(float(_draw(spec, index, "inertia_error", d.inertia_error)), _MIN_RELATIVE),
        thrust_error=tuple(float(e) for e in thrust),
        failed_thruster=failed,
        failure_time=t_fail,
        orbit_altitude=float(_draw(spec, index, "orbit_altitude", d.orbit_altitude)),
        orbit_phase=float(_draw(spec, index, "orbit_phase", d.orbit_phase)),
        density_error=max(float(_draw(spec, index, "density_error", d.density_error)), _MIN_RELATIVE),
        thruster_cant=cant,
        thruster_cant_azimuth=cant_azimuth,
        sensor_noise_error=max(float(_draw(spec, index, "sensor_noise_error", d.sensor_noise_error)), _MIN_RELATIVE),
        sensor_bias_error=max(float(_draw(spec, index, "sensor_bias_error", d.sensor_bias_error)), _MIN_RELATIVE),
    )


def gust_stream(case: FlightCase) -> np.random.Generator:
    """The stream that drives this flight's gusts (separate so gust draws never shift the case)."""
    return stream(case.seed, case.index, "wind_gust_process")
