"""One typed parameter table per sensor: name, default, unit, range and meaning.

A sensor module lists its parameters as :class:`Param` rows; :func:`parse_section` reads a scene's
``sensors.<key>`` section through the table (unknown keys, wrong types and values out of range are
:class:`~lander_sim.scenes.loader.SceneError` naming the file and the key), and :func:`table_markdown`
prints the table for docs/estimation.md, so validation and docs come from the same rows.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from lander_sim.yaml_file import Reader


@dataclass(frozen=True)
class Param:
    """One parameter of a sensor.

    ``default`` is a float, or a 3-tuple for a body-frame direction (``lo``/``hi`` then unused; the
    direction must be non-zero and is normalised). ``lo``/``hi`` bound a number (None: unbounded);
    ``strict_lo`` excludes ``lo`` itself. ``source`` says where the default comes from.
    """

    name: str
    default: float | tuple[float, float, float]
    unit: str
    meaning: str
    source: str
    lo: float | None = 0.0
    hi: float | None = None
    strict_lo: bool = False

    def check(self, value: float) -> str | None:
        """None for a good number, else what is allowed."""
        if not math.isfinite(value):
            return "expected a finite number"
        if self.lo is not None and (value < self.lo or (self.strict_lo and value == self.lo)):
            return f"expected a number {'>' if self.strict_lo else '>='} {self.lo}, got {value}"
        if self.hi is not None and value > self.hi:
            return f"expected a number <= {self.hi}, got {value}"
        return None


def defaults(table: Sequence[Param]) -> dict[str, Any]:
    """The table's defaults by name."""
    return {p.name: p.default for p in table}


def parse_section(rd: Reader, node: Any, path: str, table: Sequence[Param]) -> dict[str, Any]:
    """The values of ``node`` (a mapping, ``{}`` for all defaults) checked against ``table``."""
    m = rd.mapping(node, path, {p.name for p in table})
    out = defaults(table)
    for p in table:
        if p.name not in m:
            continue
        if isinstance(p.default, tuple):
            v = rd.vector3(m[p.name], f"{path}.{p.name}")
            n = math.sqrt(sum(x * x for x in v))
            if n == 0.0:
                raise rd.fail(f"{path}.{p.name}", "expected a non-zero direction")
            out[p.name] = (v[0] / n, v[1] / n, v[2] / n)
        else:
            x = rd.number(m[p.name], f"{path}.{p.name}")
            why = p.check(x)
            if why is not None:
                raise rd.fail(f"{path}.{p.name}", why)
            out[p.name] = x
    return out


def table_markdown(table: Sequence[Param]) -> str:
    """The table as a markdown table (name, default, unit, range, meaning, source)."""
    rows = ["| parameter | default | unit | range | meaning | source |", "| --- | --- | --- | --- | --- | --- |"]
    for p in table:
        if isinstance(p.default, tuple):
            rng = "non-zero, normalised"
            d = "[" + ", ".join(f"{x:g}" for x in p.default) + "]"
        else:
            lo = "" if p.lo is None else (f"> {p.lo:g}" if p.strict_lo else f">= {p.lo:g}")
            hi = "" if p.hi is None else f"<= {p.hi:g}"
            rng = ", ".join(s for s in (lo, hi) if s) or "any"
            d = f"{p.default:g}"
        rows.append(f"| `{p.name}` | {d} | {p.unit} | {rng} | {p.meaning} | {p.source} |")
    return "\n".join(rows)

