"""The sensors a scene switches on (scene section ``sensors:``) and the suite that samples them.

Scene form (each sensor's section holds its own parameters, ``{}`` for the defaults; a sensor
absent, null or false is off, and a scene with no ``sensors:`` has none)::

    sensors:
      seed: 7                  # integer in [0, 2**63): every sensor's noise and bias draws
      imu: {}
      star_tracker: {max_rate: 0.05}
      altimeter: {}
      doppler: {max_altitude: 2000.0}
      ground_fix: {position_noise: 500.0}

**Sampling.** Sensor ``k`` of rate ``f`` is due at ``t = j / f`` (``j = 0, 1, ...``); :meth:`SensorSuite.sample`
takes the truth at a simulation step's time and gives one measurement from every sensor due at or
before it, stamped with the step's time (a sensor faster than the step gives one sample per step,
its noise that of the interval since its previous sample, or since switch-on at ``t = 0``). **Seeds.** Sensor ``k`` (its index in
:data:`SENSORS`) draws from ``Generator(PCG64(SeedSequence([seed, k])))``: switching one sensor on
or off leaves the others' draws unchanged.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from lander_sim.yaml_file import Reader

from . import altimeter, doppler, ground_fix, imu, star_tracker
from .base import Measurement, Truth
from .params import Param, parse_section


class Sensor(Protocol):
    key: str
    rate: float
    dropouts: int

    def measure(self, truth: Truth, dt: float) -> Measurement | None: ...


#: key -> (parameter table, class), in seed-index order.
SENSORS: dict[str, tuple[tuple[Param, ...], Any]] = {
    "imu": (imu.PARAMS, imu.IMU),
    "star_tracker": (star_tracker.PARAMS, star_tracker.StarTracker),
    "altimeter": (altimeter.PARAMS, altimeter.RadarAltimeter),
    "doppler": (doppler.PARAMS, doppler.DopplerVelocimeter),
    "ground_fix": (ground_fix.PARAMS, ground_fix.GroundFix),
}


@dataclass(frozen=True)
class SensorsConfig:
    """The scene's ``sensors`` section: the seed and, for each sensor on, its parameter values."""

    seed: int = 0
    sections: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def __contains__(self, key: object) -> bool:
        return key in self.sections


def parse_sensors(rd: Reader, node: Any, path: str = "sensors") -> SensorsConfig | None:
    """``sensors:`` through :data:`SENSORS` (module docstring); None when the scene has no sensors."""
    if node is None or node is False:
        return None
    m = rd.mapping(node, path, {"seed", *SENSORS})
    seed = m.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise rd.fail(f"{path}.seed", f"expected an integer in [0, 2**63), got {seed!r}")
    sections = {key: parse_section(rd, m[key], f"{path}.{key}", table)
                for key, (table, _) in SENSORS.items() if m.get(key) not in (None, False)}
    return SensorsConfig(seed=seed, sections=sections)


def generator(seed: int, key: str) -> np.random.Generator:
    """Sensor ``key``'s generator for suite seed ``seed`` (module docstring)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, list(SENSORS).index(key)])))


class SampleSchedule:
    """When each sensor is due (module docstring, "Sampling"): sensor ``key`` of rate ``f`` is due at
    the first step time ``t >= j / f``, ``j = 0, 1, ...``. The suite samples by it, and a reader of the
    sensors' messages (the estimator node) knows from it which messages a step time brings."""

    def __init__(self, rates: Mapping[str, float]) -> None:
        self.rates = dict(rates)
        self._next = {key: 0.0 for key in self.rates}

    def due(self, t: float) -> list[str]:
        """The sensors due at step time ``t`` [s], in table order; each is then due next at its
        first instant ``j / f`` after ``t``."""
        out = []
        for key, rate in self.rates.items():
            period = 1.0 / rate
            if t < self._next[key] - 1e-9 * period:
                continue
            self._next[key] = (math.floor(t * rate + 1e-9) + 1) / rate
            out.append(key)
        return out

    def copy(self) -> SampleSchedule:
        """An independent schedule at the same point."""
        other = SampleSchedule(self.rates)
        other._next = dict(self._next)
        return other


class SensorSuite:
    """The sensors of a :class:`SensorsConfig`, sampled at their rates (module docstring)."""

    def __init__(self, config: SensorsConfig, seed: int | None = None) -> None:
        self.config = config
        self.reset(seed)

    def reset(self, seed: int | None = None) -> None:
        """Back to switch-on: fresh biases and noise from ``seed`` (None: the config's)."""
        s = self.config.seed if seed is None else seed
        self.sensors: dict[str, Sensor] = {
            key: SENSORS[key][1](dict(values), generator(s, key)) for key, values in self.config.sections.items()}
        self.schedule = SampleSchedule({key: float(sensor.rate) for key, sensor in self.sensors.items()})
        self._last: dict[str, float | None] = {key: None for key in self.sensors}

    def sample(self, truth: Truth) -> list[Measurement]:
        """One measurement from each sensor due at or before ``truth.t`` (dropouts give none), in table order."""
        return [m for _, m in self.sample_due(truth) if m is not None]

    def sample_due(self, truth: Truth) -> list[tuple[str, Measurement | None]]:
        """Each sensor due at ``truth.t`` (:class:`SampleSchedule`) with its measurement, None for a
        dropout (out of range, lost lock), in table order."""
        out: list[tuple[str, Measurement | None]] = []
        t = truth.t
        for key in self.schedule.due(t):
            sensor = self.sensors[key]
            last = self._last[key]
            # the first output averages from switch-on at t = 0 (one period when sampled at t = 0)
            dt = (t if t > 0.0 else 1.0 / sensor.rate) if last is None else t - last
            self._last[key] = t
            out.append((key, sensor.measure(truth, dt)))
        return out

    @property
    def dropouts(self) -> dict[str, int]:
        """Samples each sensor gave no output for (out of range, lost lock)."""
        return {key: s.dropouts for key, s in self.sensors.items()}
