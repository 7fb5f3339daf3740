"""A sweep specification: YAML in, a validated, typed :class:`SweepSpec` out.

Example (``sweeps/hover-robustness.yaml``)::

    name: hover-robustness
    scene: hover                 # scene name, alias ("7") or path to a scene YAML
    controllers: [combined]      # one, or several to compare on the same dispersed cases
    flights: 1000
    seed: 20240607               # master seed: flight i is drawn from (seed, i) alone
    end: {duration: 60.0}
    dispersions:
      initial_tilt: {normal: {mean: 0.0, std: 0.05}}      # rad
      mass_error: {uniform: {min: -0.02, max: 0.02}}       # relative
      thruster_failure: {probability: 0.01, time: {uniform: {min: 5, max: 40}}}

Every error is a :class:`SweepSpecError` (a ``ValueError``) whose message names the file and
the dotted key that is wrong (``dispersions.initial_tilt.normal.std``) and what was expected.
All quantities are SI: metres, seconds, radians, kg; ``*_error`` dispersions are relative, except
``thruster_cant_error`` (an angle, rad).

``navigation: estimate`` (at the top, or per controller: ``{name: landing, navigation: estimate}``)
flies the law on the navigation filter's estimate from the scene's sensors instead of the truth; the
scene needs a ``sensors`` section with the IMU, whose errors each flight draws from its own seed
(:func:`lander_tools.sweep.case_scene.sensor_seed`). The same law listed twice, once on ``truth``
and once on ``estimate`` (different labels), flies both on the very same cases.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lander_yaml import read_yaml


class SweepSpecError(ValueError):
    """A bad sweep specification; the message names the key and what was expected."""


# --------------------------------------------------------------------------- distributions


@dataclass(frozen=True)
class Distribution:
    """A scalar distribution: ``normal`` (mean, std), ``uniform`` (min, max) or ``fixed`` (value)."""

    kind: str
    a: float  # mean | min | value
    b: float = 0.0  # std | max | unused

    def sample(self, rng: np.random.Generator, size: int | None = None) -> Any:
        """Draw from ``rng``; ``size=None`` gives a float, else an array of ``size`` draws."""
        if self.kind == "normal":
            return rng.normal(self.a, self.b, size)
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b, size)
        return self.a if size is None else np.full(size, self.a)

    def describe(self) -> str:
        if self.kind == "normal":
            return f"normal(mean={self.a:g}, std={self.b:g})"
        if self.kind == "uniform":
            return f"uniform({self.a:g}, {self.b:g})"
        return f"fixed({self.a:g})"


DISTRIBUTION_KINDS = ("normal", "uniform", "fixed")


@dataclass(frozen=True)
class ThrusterFailure:
    """With ``probability``, one thruster (uniformly chosen) stops for good at a time drawn from ``time`` [s]."""

    probability: float
    time: Distribution


#: Dispersion key -> (meaning, whether each of 3 world/body axes is drawn independently).
DISPERSION_KEYS: dict[str, str] = {
    "initial_tilt": "tilt angle of the initial attitude about a random horizontal body axis [rad]",
    "initial_body_rate": "added to each body-rate component omega_B [rad/s]",
    "initial_altitude": "added to the initial altitude, along the local vertical [m]",
    "initial_velocity": "added to each world-frame velocity component v_W [m/s]",
    "wind_mean": "each world-frame component of a steady wind [m/s]",
    "wind_gust": "standard deviation of the gusts about the mean wind, per world axis [m/s]",
    "demand_altitude_step": "step in demand altitude applied at end.demand_step_time [m]",
    "mass_error": "relative error of the true dry mass vs the controller's model [-]",
    "inertia_error": "relative error of the true inertia vs the controller's model [-]",
    "thrust_error": "relative error of each thruster's true maximum thrust [-]",
    "thruster_failure": "probability and time of one thruster failing (throttle forced to 0)",
    "orbit_altitude": "change of the initial orbit's radius, the orbit scaled about the planet's centre [m]",
    "orbit_phase": "rotation of the initial position and velocity about the orbit normal r x v [rad]",
    "density_error": "relative error of the flown atmosphere's surface density vs the controller's model [-]",
    "thruster_cant_error": "tilt of each thruster's direction about a random axis perpendicular to it [rad]",
    "sensor_noise_error": "relative error of every sensor's noise parameters vs the scene's (the filter's model) [-]",
    "sensor_bias_error": "relative error of every sensor's bias and bias-walk parameters vs the scene's [-]",
}

#: Relative errors must keep the physical quantity positive.
_RELATIVE = ("mass_error", "inertia_error", "thrust_error", "density_error", "sensor_noise_error", "sensor_bias_error")
#: Quantities that are magnitudes, never negative.
_NON_NEGATIVE = ("wind_gust",)


@dataclass(frozen=True)
class Dispersions:
    """What is dispersed from flight to flight; ``None`` means not dispersed (the scene's value)."""

    initial_tilt: Distribution | None = None
    initial_body_rate: Distribution | None = None
    initial_altitude: Distribution | None = None
    initial_velocity: Distribution | None = None
    wind_mean: Distribution | None = None
    wind_gust: Distribution | None = None
    demand_altitude_step: Distribution | None = None
    mass_error: Distribution | None = None
    inertia_error: Distribution | None = None
    thrust_error: Distribution | None = None
    thruster_failure: ThrusterFailure | None = None
    orbit_altitude: Distribution | None = None
    orbit_phase: Distribution | None = None
    density_error: Distribution | None = None
    thruster_cant_error: Distribution | None = None
    sensor_noise_error: Distribution | None = None
    sensor_bias_error: Distribution | None = None


# --------------------------------------------------------------------------- the rest of the spec


@dataclass(frozen=True)
class EndCondition:
    """When a flight ends and how it is judged.

    Attributes
    ----------
    duration : float
        Simulated time of a flight [s]; it ends earlier on touchdown (landed or crashed).
    demand_step_time : float
        Time of the demand-altitude step [s] (when that dispersion is on).
    hover_window : float
        The hover error is the RMS altitude error over the last ``hover_window`` seconds [s].
    settle_band : float
        Settled once ``|altitude error|`` stays below this for good [m].
    gust_time_constant : float
        Correlation time of the first-order Gauss-Markov gusts [s].
    max_hover_error : float
        Success needs a hover error at most this [m] ...
    max_tilt : float
        ... a tilt from the local vertical never above this [rad] ...
    allow_touchdown : bool
        ... and no touchdown unless this is true.
    land : bool
        A landing sweep: success is instead a touchdown the scene classifies ``safe`` with the
        descent rate, ground speed and tilt below the three ``max_touchdown_*`` limits.
    max_touchdown_descent_rate, max_touchdown_ground_speed : float
        [m/s] (landing sweeps).
    max_touchdown_tilt : float
        [rad] (landing sweeps).
    hover_hold : float
        A hover-hold sweep when > 0 [s] (the de-orbit sweeps): success is instead the hover reached
        and held, ``|altitude - demand| <= hover_band`` and ``|v_W| <= hover_speed`` at every control
        instant of a run at least ``hover_hold`` long; the flight stops there. It fails when the
        duration ends first, on any touchdown, or when it diverges. 0: off.
    hover_band : float
        [m] (hover-hold sweeps).
    hover_speed : float
        Total speed ``|v_W|`` [m/s] (hover-hold sweeps).
    """

    duration: float = 60.0
    demand_step_time: float = 10.0
    hover_window: float = 10.0
    settle_band: float = 1.0
    gust_time_constant: float = 2.0
    max_hover_error: float = 2.0
    max_tilt: float = 0.5
    allow_touchdown: bool = False
    land: bool = False
    max_touchdown_descent_rate: float = 1.0
    max_touchdown_ground_speed: float = 1.0
    max_touchdown_tilt: float = 0.5
    hover_hold: float = 0.0
    hover_band: float = 2.0
    hover_speed: float = 0.2


@dataclass(frozen=True)
class ControllerChoice:
    """A controller to fly: registry name, parameters, and the label used in tables."""

    name: str
    params: Mapping[str, Any] = field(default_factory=dict)
    label: str = ""
    #: What the law flies on: ``truth`` (the simulator's state) or ``estimate`` (the navigation
    #: filter's, from the scene's sensors: lander_autopilot.estimation.onboard).
    navigation: str = "truth"


#: Per-flight metrics a sweep can keep (flight.py computes them all; the spec chooses).
METRICS: dict[str, str] = {
    "touchdown_speed": "speed at touchdown [m/s] (NaN when no touchdown)",
    "hover_error": "RMS altitude error over the hover window [m]",
    "final_altitude_error": "altitude minus demand at the end [m]",
    "settling_time": "time from the last demand change to staying inside the settle band [s]",
    "fuel_used": "fuel burnt [kg]",
    "saturation_time": "time with the controller's output saturated [s]",
    "max_tilt": "largest angle between body z and the local vertical [rad]",
    "max_body_rate": "largest |omega_B| [rad/s]",
    "flight_time": "simulated time flown [s]",
    "touchdown_descent_rate": "descent rate at touchdown [m/s] (NaN when no touchdown)",
    "touchdown_ground_speed": "ground speed at touchdown [m/s] (NaN when no touchdown)",
    "touchdown_tilt": "tilt of body z from the local vertical at touchdown [deg] (NaN when no touchdown)",
    "hover_time": "when the held hover window began (end.hover_hold) [s] (NaN when not held)",
    "fuel_left": "fuel in the tank at the end of the flight [kg]",
    "powered_fuel": "fuel burnt from the controller's first powered-descent mode to its first hover mode [kg] "
                    "(NaN when either is absent)",
    "powered_optimum": "minimum fuel from the state at the first powered-descent mode to rest at the demand, "
                       "convex (lossless convexification, the flown vehicle and atmosphere) [kg] (core-only; NaN "
                       "without both modes)",
    "fuel_ratio": "fuel from the first powered-descent to the first instant within end.hover_band and "
                  "end.hover_speed, over powered_optimum [x optimum] (core-only; NaN without both)",
    "powered_optimum_balanced": "powered_optimum with the thrust bound the flown thrusters give with no torque "
                                "(design.altitude.balanced_thrust: less than every thruster flat out when their "
                                "thrust or cant is off) [kg] (core-only; NaN without both modes)",
    "fuel_ratio_balanced": "fuel_ratio over powered_optimum_balanced: against the least fuel the rigid vehicle can "
                           "reach with no other torque (the canopy's can beat it) [x optimum] (core-only; NaN "
                           "without both)",
    "compute_time": "CPU time in the controller's update calls over the flight, time.process_time [s] "
                    "(not deterministic; NaN on the batched path)",
    "mpc_solve_time_p99": "99th percentile of the MPC's solve times, from controller.diagnostics() [s] "
                          "(not deterministic; NaN without)",
    "mpc_solve_time_median": "median of the MPC's solve times, from controller.diagnostics() [s] "
                             "(not deterministic; NaN without)",
}

#: The metrics a spec without ``metrics:`` keeps: every one up to the de-orbit sweeps' (those are asked
#: for by name: they are NaN or meaningless elsewhere, and ``compute_time`` is not deterministic).
DEFAULT_METRICS: tuple[str, ...] = tuple(METRICS)[:tuple(METRICS).index("hover_time")]

#: Metrics that are measured, not computed: they differ from run to run of the same flight, so every
#: determinism check (replay, parallel vs serial, batched vs per-flight, through ROS) leaves them out.
NONDETERMINISTIC_METRICS: tuple[str, ...] = ("compute_time", "mpc_solve_time_p99", "mpc_solve_time_median")

#: Metrics only the core-only loop computes (a convex solve from the simulator's own state at the
#: handover): a bag's row has NaN, so the through-ROS comparison leaves them out.
CORE_ONLY_METRICS: tuple[str, ...] = ("powered_optimum", "fuel_ratio", "powered_optimum_balanced", "fuel_ratio_balanced")


def metric_unit(metric: str) -> str:
    """The unit of a metric: what its description in :data:`METRICS` has in brackets (``-`` if none)."""
    desc = METRICS.get(metric, "")
    return desc[desc.find("[") + 1:desc.find("]")] if "[" in desc else "-"


def metric_label(metric: str) -> str:
    """``"hover_error [m]"``: the metric's name with its unit (tables and plot axes)."""
    return f"{metric} [{metric_unit(metric)}]"


@dataclass(frozen=True)
class Bound:
    """A per-flight bound on one metric: each flight's value must be ``<= max`` and ``>= min`` (None: no
    bound that side); a flight where the metric is undefined (NaN: it never got there) is outside."""

    metric: str
    max: float | None = None
    min: float | None = None

    def holds(self, value: float) -> bool:
        return (math.isfinite(value) and (self.max is None or value <= self.max)
                and (self.min is None or value >= self.min))

    def describe(self) -> str:
        parts = ([f">= {self.min:g}"] if self.min is not None else []) + ([f"<= {self.max:g}"] if self.max is not None else [])
        unit = metric_unit(self.metric)
        return f"{self.metric} {' and '.join(parts)}" + ("" if unit == "-" else f" {unit}")


@dataclass(frozen=True)
class Acceptance:
    """What a controller must achieve over the sweep (the ``acceptance`` key), checked and printed per
    controller: the success rate, the lower bound of its Wilson interval (fractions in [0, 1]), and
    per-flight bounds on metrics (every flight within, the ones outside named)."""

    success_rate: float | None = None
    success_wilson_low: float | None = None
    bounds: tuple[Bound, ...] = ()


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep specification (see the module docstring for the YAML)."""

    name: str
    scene: str
    controllers: tuple[ControllerChoice, ...]
    flights: int
    seed: int
    end: EndCondition
    dispersions: Dispersions
    metrics: tuple[str, ...]
    #: Controller update rate [Hz]; None: every simulation step, as the original program's autopilot.
    control_rate: float | None = None
    source: str = "<dict>"
    acceptance: Acceptance = Acceptance()


TOP_KEYS = (
    "name", "scene", "controllers", "controller", "flights", "seed", "control_rate", "end", "dispersions", "metrics",
    "acceptance", "navigation",
)

#: What a law can fly on (``navigation``, per spec or per controller).
NAVIGATION = ("truth", "estimate")


# --------------------------------------------------------------------------- parsing helpers


class _Ctx:
    """Where we are (file and dotted key) so every error can name it."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, msg: str) -> SweepSpecError:
        return SweepSpecError(f"{self.source}: {key}: {msg}")


def _mapping(ctx: _Ctx, key: str, value: Any) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ctx.fail(key, f"expected a mapping, got {type(value).__name__} {value!r}")
    return value


def _check_keys(ctx: _Ctx, prefix: str, data: Mapping[str, Any], allowed: tuple[str, ...] | list[str]) -> None:
    for k in data:
        if k not in allowed:
            where = f"{prefix}.{k}" if prefix else str(k)
            raise ctx.fail(where, f"unknown key; allowed keys: {', '.join(allowed)}")


def _number(ctx: _Ctx, key: str, value: Any, *, positive: bool = False, non_negative: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ctx.fail(key, f"expected a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ctx.fail(key, f"expected a finite number, got {value!r}")
    if positive and x <= 0.0:
        raise ctx.fail(key, f"must be > 0, got {value!r}")
    if non_negative and x < 0.0:
        raise ctx.fail(key, f"must be >= 0, got {value!r}")
    return x


def _integer(ctx: _Ctx, key: str, value: Any, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ctx.fail(key, f"expected an integer, got {value!r}")
    if value < minimum:
        raise ctx.fail(key, f"must be >= {minimum}, got {value!r}")
    return value


def _distribution(ctx: _Ctx, key: str, value: Any) -> Distribution:
    """``{normal: {mean, std}}``, ``{uniform: {min, max}}``, ``{fixed: value}`` or a bare number (fixed)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return Distribution("fixed", _number(ctx, key, value))
    data = _mapping(ctx, key, value)
    if len(data) != 1 or next(iter(data)) not in DISTRIBUTION_KINDS:
        raise ctx.fail(key, f"expected exactly one of {', '.join(DISTRIBUTION_KINDS)}, got keys {list(data)}")
    kind, params = next(iter(data.items()))
    k = f"{key}.{kind}"
    if kind == "fixed":
        return Distribution("fixed", _number(ctx, k, params))
    params = _mapping(ctx, k, params)
    names = ("mean", "std") if kind == "normal" else ("min", "max")
    _check_keys(ctx, k, params, names)
    for n in names:
        if n not in params:
            raise ctx.fail(f"{k}.{n}", "missing")
    a = _number(ctx, f"{k}.{names[0]}", params[names[0]])
    b = _number(ctx, f"{k}.{names[1]}", params[names[1]])
    if kind == "normal" and b < 0.0:
        raise ctx.fail(f"{k}.std", f"a standard deviation must be >= 0, got {b!r}")
    if kind == "uniform" and a > b:
        raise ctx.fail(f"{k}.min", f"min ({a!r}) is greater than max ({b!r})")
    return Distribution(kind, a, b)


def _support(d: Distribution) -> tuple[float, float]:
    """Smallest and largest values the distribution can realistically draw (normal: mean +- 6 std)."""
    if d.kind == "normal":
        return d.a - 6.0 * d.b, d.a + 6.0 * d.b
    if d.kind == "uniform":
        return d.a, d.b
    return d.a, d.a


def _dispersions(ctx: _Ctx, value: Any) -> Dispersions:
    if value is None:
        return Dispersions()
    data = _mapping(ctx, "dispersions", value)
    _check_keys(ctx, "dispersions", data, list(DISPERSION_KEYS))
    out: dict[str, Any] = {}
    for name, raw in data.items():
        key = f"dispersions.{name}"
        if name == "thruster_failure":
            tf = _mapping(ctx, key, raw)
            _check_keys(ctx, key, tf, ("probability", "time"))
            if "probability" not in tf:
                raise ctx.fail(f"{key}.probability", "missing")
            p = _number(ctx, f"{key}.probability", tf["probability"])
            if not 0.0 <= p <= 1.0:
                raise ctx.fail(f"{key}.probability", f"a probability must be in [0, 1], got {p!r}")
            t = _distribution(ctx, f"{key}.time", tf.get("time", 0.0))
            if _support(t)[0] < 0.0 and t.kind != "normal":
                raise ctx.fail(f"{key}.time", f"failure time must be >= 0 s, got {t.describe()}")
            out[name] = ThrusterFailure(p, t)
            continue
        d = _distribution(ctx, key, raw)
        lo, _ = _support(d)
        if name in _RELATIVE and d.kind != "normal" and lo <= -1.0:
            # A relative error of -100 % or less makes a mass, inertia or thrust zero or negative.
            raise ctx.fail(key, f"relative error must stay above -1 (-100 %), got {d.describe()}")
        if name in _RELATIVE and d.kind == "normal" and d.b > 0.2:
            raise ctx.fail(key, f"relative error std must be <= 0.2 so the drawn quantity stays positive, got {d.b!r}")
        if name in _NON_NEGATIVE and d.kind != "normal" and lo < 0.0:
            raise ctx.fail(key, f"must be >= 0 (it is a magnitude), got {d.describe()}")
        if name in _NON_NEGATIVE and d.kind == "normal":
            raise ctx.fail(key, "a magnitude must be drawn from uniform or fixed, not normal")
        if name == "thruster_cant_error" and not max(abs(x) for x in _support(d)) < math.pi / 2:
            # A tilt of 90 degrees or more turns a thruster sideways or backwards: not a cant error.
            raise ctx.fail(key, f"a cant error must stay under pi/2 rad (90 deg) in magnitude, got {d.describe()}"
                           + (" (normal: mean +- 6 std)" if d.kind == "normal" else ""))
        out[name] = d
    return Dispersions(**out)


def _navigation(ctx: _Ctx, key: str, value: Any) -> str:
    if value not in NAVIGATION:
        raise ctx.fail(key, f"expected one of {', '.join(NAVIGATION)}, got {value!r}")
    return str(value)


def _controllers(ctx: _Ctx, data: Mapping[str, Any]) -> tuple[ControllerChoice, ...]:
    if "controllers" in data and "controller" in data:
        raise ctx.fail("controller", "give either controller or controllers, not both")
    raw = data.get("controllers", data.get("controller"))
    key = "controllers" if "controllers" in data else "controller"
    if raw is None:
        raise ctx.fail("controllers", "missing: name at least one controller (e.g. combined)")
    items = raw if isinstance(raw, list) else [raw]
    if not items:
        raise ctx.fail(key, "empty: name at least one controller")
    default_nav = _navigation(ctx, "navigation", data.get("navigation", "truth"))
    out: list[ControllerChoice] = []
    for i, item in enumerate(items):
        k = f"{key}[{i}]" if isinstance(raw, list) else key
        if isinstance(item, str):
            out.append(ControllerChoice(item, {}, item, default_nav))
            continue
        m = _mapping(ctx, k, item)
        _check_keys(ctx, k, m, ("name", "params", "label", "navigation"))
        if not isinstance(m.get("name"), str):
            raise ctx.fail(f"{k}.name", f"expected a controller name, got {m.get('name')!r}")
        params = dict(_mapping(ctx, f"{k}.params", m.get("params", {}) or {}))
        label = m.get("label", m["name"])
        if not isinstance(label, str):
            raise ctx.fail(f"{k}.label", f"expected a string, got {label!r}")
        nav = _navigation(ctx, f"{k}.navigation", m.get("navigation", default_nav))
        out.append(ControllerChoice(m["name"], params, label, nav))
    labels = [c.label for c in out]
    if len(set(labels)) != len(labels):
        raise ctx.fail(key, f"controller labels must differ (give each a label), got {labels}")
    return tuple(out)


def _end(ctx: _Ctx, value: Any) -> EndCondition:
    data = _mapping(ctx, "end", value or {})
    defaults = EndCondition()
    names = tuple(EndCondition.__dataclass_fields__)
    _check_keys(ctx, "end", data, names)
    kw: dict[str, Any] = {}
    for n, v in data.items():
        if n in ("allow_touchdown", "land"):
            if not isinstance(v, bool):
                raise ctx.fail(f"end.{n}", f"expected true or false, got {v!r}")
            kw[n] = v
        elif n == "demand_step_time":
            kw[n] = _number(ctx, f"end.{n}", v, non_negative=True)
        else:
            kw[n] = _number(ctx, f"end.{n}", v, positive=True)
    end = EndCondition(**{**defaults.__dict__, **kw})
    if end.hover_window > end.duration:
        raise ctx.fail("end.hover_window", f"({end.hover_window} s) is longer than end.duration ({end.duration} s)")
    if "hover_hold" not in data:
        for n in ("hover_band", "hover_speed"):
            if n in data:
                raise ctx.fail(f"end.{n}", "only applies to a hover-hold sweep: give end.hover_hold too")
    elif end.hover_hold > end.duration:
        raise ctx.fail("end.hover_hold", f"({end.hover_hold} s) is longer than end.duration ({end.duration} s)")
    elif end.land:
        raise ctx.fail("end.hover_hold", "a sweep is judged either by a held hover or by a landing (end.land), not both")
    return end


def _acceptance(ctx: _Ctx, value: Any, metrics: tuple[str, ...]) -> Acceptance:
    data = _mapping(ctx, "acceptance", value or {})
    _check_keys(ctx, "acceptance", data, ("success_rate", "success_wilson_low", "bounds"))
    kw: dict[str, Any] = {}
    for n in ("success_rate", "success_wilson_low"):
        if n in data:
            x = _number(ctx, f"acceptance.{n}", data[n], non_negative=True)
            if x > 1.0:
                raise ctx.fail(f"acceptance.{n}", f"a fraction in [0, 1] (0.95, not 95), got {data[n]!r}")
            kw[n] = x
    bounds = []
    for metric, raw in _mapping(ctx, "acceptance.bounds", data.get("bounds", {}) or {}).items():
        key = f"acceptance.bounds.{metric}"
        if metric not in metrics:
            raise ctx.fail(key, f"not among the sweep's metrics ({', '.join(metrics)}): add it to metrics")
        b = _mapping(ctx, key, raw)
        _check_keys(ctx, key, b, ("max", "min"))
        if not b:
            raise ctx.fail(key, "give max, min or both")
        lo = _number(ctx, f"{key}.min", b["min"]) if "min" in b else None
        hi = _number(ctx, f"{key}.max", b["max"]) if "max" in b else None
        if lo is not None and hi is not None and lo > hi:
            raise ctx.fail(key, f"min ({lo:g}) is above max ({hi:g})")
        bounds.append(Bound(metric, max=hi, min=lo))
    return Acceptance(**kw, bounds=tuple(bounds))


def parse_spec(data: Any, source: str = "<dict>") -> SweepSpec:
    """Validate a YAML-shaped mapping into a :class:`SweepSpec`.

    Raises
    ------
    SweepSpecError
        Naming ``source`` and the dotted key: unknown key, missing key, wrong type, a negative
        count, an impossible dispersion (negative std, min > max, probability outside [0, 1]), or an
        acceptance bound on a metric the sweep does not record.
    """
    ctx = _Ctx(source)
    data = _mapping(ctx, "<top level>", data)
    _check_keys(ctx, "", data, TOP_KEYS)
    for required in ("scene", "flights"):
        if required not in data:
            raise ctx.fail(required, "missing")
    scene = data["scene"]
    if isinstance(scene, int) and not isinstance(scene, bool):
        scene = str(scene)  # scenario numbers are aliases: `scene: 7`
    if not isinstance(scene, str) or not scene:
        raise ctx.fail("scene", f"expected a scene name, alias or path, got {scene!r}")
    name = data.get("name", Path(source).stem if source != "<dict>" else "sweep")
    if not isinstance(name, str):
        raise ctx.fail("name", f"expected a string, got {name!r}")
    metrics_raw = data.get("metrics", list(DEFAULT_METRICS))
    if not isinstance(metrics_raw, list) or not metrics_raw:
        raise ctx.fail("metrics", f"expected a non-empty list of metric names, got {metrics_raw!r}")
    for i, m in enumerate(metrics_raw):
        if m not in METRICS:
            raise ctx.fail(f"metrics[{i}]", f"unknown metric {m!r}; choose from: {', '.join(METRICS)}")
    return SweepSpec(
        name=name,
        scene=scene,
        controllers=_controllers(ctx, data),
        flights=_integer(ctx, "flights", data["flights"], minimum=1),
        seed=_integer(ctx, "seed", data.get("seed", 0), minimum=0),
        end=_end(ctx, data.get("end")),
        dispersions=_dispersions(ctx, data.get("dispersions")),
        metrics=tuple(metrics_raw),
        control_rate=(
            None if data.get("control_rate") is None
            else _number(ctx, "control_rate", data["control_rate"], positive=True)
        ),
        source=source,
        acceptance=_acceptance(ctx, data.get("acceptance"), tuple(metrics_raw)),
    )


def load_spec(path: str | Path) -> SweepSpec:
    """Read and validate a sweep YAML file; errors name the file and the key."""
    p = Path(path)
    return parse_spec(read_yaml(p, "sweep spec", SweepSpecError), str(p))
