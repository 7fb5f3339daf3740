"""Controller registry: built-ins plus third-party plug-ins from the entry-point group
``mars_lander.controllers``.

A plug-in package declares, in its ``pyproject.toml``::

    [project.entry-points."mars_lander.controllers"]
    my-law = "my_package.module:MyController"

where ``MyController(vehicle, **params)`` returns an object with ``name``, ``reset()`` and
``update(t, state, demand) -> ControlOutput`` (subclassing :class:`~.base.Controller` is the
easy way). No change to this package is needed. Built-in names win over plug-ins of the same name.
"""
from __future__ import annotations

import importlib
import inspect
import typing
from collections.abc import Callable, Iterator, Mapping
from importlib.metadata import entry_points
from typing import Any

from lander_sim.physics.vehicle import Vehicle

from ..design import DesignError
from .base import Controller, ControllerError
from .params import ParamTable

ENTRY_POINT_GROUP = "mars_lander.controllers"

Factory = Callable[..., Any]


class _Builtins(Mapping[str, Factory]):
    """The built-in laws by name, each class imported when first asked for: a process that flies
    one law does not import the others (the de-orbit laws bring numba's kernels, the convex
    solvers and scipy: about 0.8 s of a node's start-up)."""

    def __init__(self, where: dict[str, str]) -> None:
        self._where = where  # name -> "module:class" (module relative to this package)
        self._loaded: dict[str, Factory] = {}

    def __getitem__(self, name: str) -> Factory:
        if name not in self._loaded:
            module, cls = self._where[name].split(":")
            self._loaded[name] = getattr(importlib.import_module(module, __package__), cls)
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._where)

    def __len__(self) -> int:
        return len(self._where)


#: Built-in controllers by their ``name`` (each class's ``name`` attribute; a test checks they agree).
BUILTINS: Mapping[str, Factory] = _Builtins({
    "baseline": ".altitude:BaselineController",
    "altitude": ".altitude:AltitudeController",
    "altitude-p": ".altitude:AltitudePController",
    "altitude-integral": ".altitude:IntegralAltitudeController",
    "attitude-euler": ".attitude:EulerAttitudeController",
    "attitude-quaternion": ".attitude:QuaternionAttitudeController",
    "combined": ".combined:CombinedController",
    "combined-quaternion": ".combined:CombinedQuaternionController",
    "integral": ".combined:IntegralController",
    "lqr": ".combined:LQRController",
    "ground-speed": ".ground_speed:GroundSpeedController",
    "landing": ".landing:LandingController",
    "deorbit": ".deorbit:DeorbitController",
    "deorbit-mpc": ".deorbit_mpc:DeorbitMpcController",
})


def _plugins() -> dict[str, Any]:
    """Entry points of the plug-in group, by name (loaded lazily by :func:`make_controller`)."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_controllers() -> list[str]:
    """Names of every controller that :func:`make_controller` accepts, sorted."""
    return sorted(set(BUILTINS) | set(_plugins()))


def _accepted(factory: Factory) -> list[str] | None:
    """The keyword parameters ``factory`` takes after the vehicle, sorted: its parameter table's
    (:class:`~.params.ParamTable` as ``PARAMS``: every built-in law has one) if it has one, else its
    signature's (a plug-in's); ``None`` if it takes any (a plain ``**params``: it checks them
    itself). ``**params: Unpack[SomeTypedDict]`` takes that TypedDict's keys."""
    table = getattr(factory, "PARAMS", None)
    if isinstance(table, ParamTable):
        return sorted(table.names)
    try:
        ps = list(inspect.signature(factory, eval_str=True).parameters.values())
    except Exception:  # noqa: BLE001 - a plug-in's annotations may not evaluate here: read them as written
        ps = list(inspect.signature(factory).parameters.values())
    names = {p.name for p in ps if p.kind is p.KEYWORD_ONLY or (p.kind is p.POSITIONAL_OR_KEYWORD and p.name != "vehicle")}
    for p in ps:
        if p.kind is p.VAR_KEYWORD:
            typed = typing.get_args(p.annotation) if typing.get_origin(p.annotation) is typing.Unpack else ()
            if len(typed) != 1 or not typing.is_typeddict(typed[0]):
                return None
            names |= set(typed[0].__annotations__)
    return sorted(names)


def _check_params(name: str, factory: Factory, params: dict[str, object]) -> None:
    """Unknown parameter names fail with the list of accepted ones (not a bare TypeError)."""
    allowed = _accepted(factory)
    if allowed is None:
        return  # a plug-in taking **params validates them itself
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ControllerError(
            f"controller {name!r}: unknown parameter(s) {', '.join(unknown)}; accepted: {', '.join(allowed) or '(none)'}"
        )


def _factory(name: str) -> Factory:
    """The factory of controller ``name``: a built-in or an entry-point plug-in (loaded);
    ControllerError naming the available ones for an unknown name."""
    factory: Factory | None = BUILTINS.get(name)
    if factory is None:
        ep = _plugins().get(name)
        if ep is None:
            raise ControllerError(f"unknown controller {name!r}; available: {', '.join(available_controllers())}")
        factory = ep.load()
    return factory


def parameter_table(name: str) -> ParamTable | None:
    """The parameter table of controller ``name`` (every built-in law has one; None for a plug-in
    without one); ControllerError for an unknown name."""
    factory = _factory(name)
    table = getattr(factory, "PARAMS", None)
    return table if isinstance(table, ParamTable) else None


def accepted_parameters(name: str) -> list[str] | None:
    """The keyword parameters controller ``name`` accepts, sorted (None: it checks them itself)."""
    factory = _factory(name)
    return _accepted(factory)


def controller_axes(name: str) -> tuple[str, ...]:
    """The linear models whose axes controller ``name`` controls (its class's ``AXES``:
    ``"altitude"``, ``"attitude"``; () for a plug-in that declares none); ControllerError for an
    unknown name."""
    return tuple(getattr(_factory(name), "AXES", ()))


def make_controller(name: str, vehicle: Vehicle, **params: object) -> Controller:
    """Build controller ``name`` for ``vehicle`` with ``params``.

    Raises :class:`ControllerError` (a ``ValueError``) for an unknown name (listing the valid
    ones), an unknown parameter (listing the accepted ones), or a parameter of the wrong
    shape or value (naming it and the expected shape).
    """
    factory = _factory(name)
    _check_params(name, factory, params)
    try:
        ctrl = factory(vehicle, **params)
    except ControllerError:
        raise
    except DesignError as exc:
        raise ControllerError(f"controller {name!r}: {exc}") from None
    for attr in ("name", "reset", "update"):
        if not hasattr(ctrl, attr):
            raise ControllerError(f"controller {name!r} from {factory!r} has no {attr!r}: not a controller")
    return ctrl
