"""Parameter tables of the controllers: one typed row per parameter (name, default, unit, valid
range, one-line meaning), from which a law's constructor validates its keywords, the registry
names an unknown one, and ``lander controllers NAME`` prints (``--markdown``: the table the docs
carry between ``<!-- params: NAME -->`` and ``<!-- /params -->``).

A row's ``check`` turns the value given into the one the law uses, or raises
:class:`~.base.ControllerError` with a line naming the parameter, the value and the valid range
(``"chute_margin: expected a number in (0, 1], got 1.5"``). Checks that compare two parameters
(a height below ``hover_band``) are the law's own, after the table's.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from ._params import matrix_param, non_negative_param, poles_param, positive_param
from .base import ControllerError

#: A row's check: ``(name, value) -> value the law uses``; raises ControllerError naming both.
Check = Callable[[str, object], object]


@dataclass(frozen=True)
class Param:
    """One parameter of a law: ``default`` (what the law uses when the parameter is not given),
    ``unit`` (SI; ``"-"`` for a pure number), ``range`` (the valid values, as the error prints them),
    ``meaning`` (one line) and ``check``."""

    name: str
    default: object
    unit: str
    range: str
    meaning: str
    check: Check

    def renamed(self, name: str, meaning: str) -> Param:
        """This row under another name: a part's parameter as the law composed of parts takes it
        (``poles`` of the altitude part as ``altitude_poles``), with the part's unit, range and check."""
        return dataclasses.replace(self, name=name, meaning=meaning)

    def with_default(self, default: object) -> Param:
        """This row with another default (a law that uses the part with another setting)."""
        return dataclasses.replace(self, default=default)


class ParamTable:
    """The parameters of one law, in the order they are documented."""

    def __init__(self, rows: Iterable[Param]) -> None:
        self.rows: tuple[Param, ...] = tuple(rows)
        self._by_name = {p.name: p for p in self.rows}
        if len(self._by_name) != len(self.rows):
            raise ValueError("a parameter table names a parameter twice")

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __getitem__(self, name: str) -> Param:
        return self._by_name[name]

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.rows]

    def defaults(self) -> dict[str, object]:
        return {p.name: p.default for p in self.rows}

    def resolve(self, given: Mapping[str, object], law: str) -> dict[str, object]:
        """Every parameter's value for ``law``: ``given`` over the defaults, each checked by its row
        (in the table's order). An unknown name fails with the list of accepted ones."""
        unknown = sorted(set(given) - set(self._by_name))
        if unknown:
            raise ControllerError(
                f"controller {law!r}: unknown parameter(s) {', '.join(unknown)}; accepted: {', '.join(sorted(self.names))}")
        return {p.name: p.check(p.name, given.get(p.name, p.default)) for p in self.rows}

    def text(self) -> str:
        """The table as aligned plain text (``lander controllers NAME``)."""
        head = ("name", "default", "unit", "range", "meaning")
        rows = [head] + [(p.name, format_default(p.default), p.unit, p.range, p.meaning) for p in self.rows]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        return "\n".join("  ".join(r[i].ljust(widths[i]) for i in range(4)) + "  " + r[4] for r in rows)

    def markdown(self) -> str:
        """The table as Markdown (``lander controllers NAME --markdown``; the docs' generated blocks)."""
        lines = ["| parameter | default | unit | range | meaning |", "|---|---|---|---|---|"]
        for p in self.rows:
            cells = (f"`{p.name}`", f"`{format_default(p.default)}`", p.unit, p.range, p.meaning)
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        return "\n".join(lines)


def format_default(value: object) -> str:
    """A default as a user writes it in a flight's or sweep's YAML (``--params``)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        if len(value) > 1 and all(v == value[0] for v in value):
            return f"[{format_default(value[0])}] x {len(value)}"
        return "[" + ", ".join(format_default(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(value)
    return str(value)


# --- checks -------------------------------------------------------------------------------------


def positive(name: str, value: object) -> object:
    return positive_param(name, value)


def non_negative(name: str, value: object) -> object:
    return non_negative_param(name, value)


def finite(name: str, value: object) -> object:
    try:
        return float(matrix_param(name, value, ()))
    except ControllerError:
        raise ControllerError(f"{name}: expected a finite number, got {value!r}") from None


def fraction_open(name: str, value: object) -> object:
    """A fraction in (0, 1)."""
    x = positive_param(name, value)
    if x >= 1.0:
        raise ControllerError(f"{name}: expected a fraction in (0, 1), got {value!r}")
    return x


def fraction(name: str, value: object) -> object:
    """A fraction in (0, 1]."""
    x = positive_param(name, value)
    if x > 1.0:
        raise ControllerError(f"{name}: expected a fraction in (0, 1], got {value!r}")
    return x


def share(name: str, value: object) -> object:
    """A share in [0, 1)."""
    x = non_negative_param(name, value)
    if x >= 1.0:
        raise ControllerError(f"{name}: expected a share in [0, 1), got {value!r}")
    return x


def boolean(name: str, value: object) -> object:
    if not isinstance(value, (bool, np.bool_)):
        raise ControllerError(f"{name}: expected true or false, got {value!r}")
    return bool(value)


def negative(name: str, value: object) -> object:
    """A negative number (a pole [1/s]); kept as given (int or float)."""
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0):
        raise ControllerError(f"{name}: expected a negative number [1/s], got {value!r}")
    return value


def poles(n: int) -> Check:
    """``n`` poles in the left half plane; the value is passed on as given (the design converts it)."""
    def check(name: str, value: object) -> object:
        poles_param(name, value, n)
        return value
    return check


def integer_at_least(low: int) -> Check:
    def check(name: str, value: object) -> object:
        if not isinstance(value, int) or value < low:
            raise ControllerError(f"{name}: expected an integer >= {low}, got {value!r}")
        return value
    return check


def at_most(limit: float, text: str) -> Check:
    """A positive number at most ``limit`` (``text``: the limit as the error prints it)."""
    def check(name: str, value: object) -> object:
        x = positive_param(name, value)
        if x > limit:
            raise ControllerError(f"{name}: expected at most {text}, got {value!r}")
        return x
    return check


def below(limit: float, text: str) -> Check:
    """A positive number under ``limit``."""
    def check(name: str, value: object) -> object:
        x = positive_param(name, value)
        if x >= limit:
            raise ControllerError(f"{name}: expected a value below {text}, got {x}")
        return x
    return check


def angle_in(low: float, high: float, text: str) -> Check:
    """An angle [rad] in ``[low, high)``."""
    def check(name: str, value: object) -> object:
        try:
            x = float(value)  # type: ignore[arg-type]  # any object: float() itself is the check
        except (TypeError, ValueError):
            raise ControllerError(f"{name}: expected a value in {text} rad, got {value!r}") from None
        if not (low <= x < high):
            raise ControllerError(f"{name}: expected a value in {text} rad, got {value!r}")
        return x
    return check


def optional(check: Check) -> Check:
    """None (the law's own choice) or a value ``check`` accepts."""
    def wrapped(name: str, value: object) -> object:
        return None if value is None else check(name, value)
    return wrapped


def design_fuel(name: str, value: object) -> object:
    """None (the full tank) or a positive fuel mass [kg]; passed on as given."""
    if value is not None:
        positive_param(name, value)
    return value


def matrix(shape: tuple[int, ...]) -> Check:
    """A finite numeric array of exactly ``shape``; passed on as given (the law converts it)."""
    def check(name: str, value: object) -> object:
        matrix_param(name, value, shape)
        return value
    return check


def weights(n: int) -> Check:
    """``n`` finite numbers >= 0 (the diagonal of an LQR state weight); passed on as given."""
    def check(name: str, value: object) -> object:
        w = matrix_param(name, value, (n,))
        if np.any(w < 0.0):
            raise ControllerError(f"{name}: expected {n} numbers >= 0, got {w.tolist()}")
        return value
    return check


def lqr_weights(name: str, value: object) -> object:
    """``[q_int, q_e, r]``: two state weights >= 0 and an input weight > 0; passed on as given."""
    w = matrix_param(name, value, (3,))
    if w[0] < 0.0 or w[1] < 0.0 or w[2] <= 0.0:
        raise ControllerError(f"{name}: expected [q_int >= 0, q_e >= 0, r > 0], got {w.tolist()}")
    return value


def any_value(name: str, value: object) -> object:
    """Checked by the law itself (a matrix whose shape depends on the vehicle)."""
    return value


PI_2 = math.pi / 2

#: Every law's ``design_fuel``: the fuel its gains are designed at (the model's mass, eq 16 and 25-26).
DESIGN_FUEL = Param("design_fuel", None, "kg", "none or > 0", "fuel the law's gains are designed at (none: a full tank)",
                    design_fuel)
