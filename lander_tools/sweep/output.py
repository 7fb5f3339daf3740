"""Write a sweep's results: per-flight table (CSV, JSON, Parquet when pyarrow is installed) and summary.

:class:`RowTable` keeps a sweep's rows compact: columns (float64, int64, bool, or references to
shared objects such as the outcome strings) of about 8 bytes per value, instead of a dict of Python
objects per row (about 2 kB each); it reads as a sequence of rows, each a read-only mapping
(:class:`Row`) whose values are the very Python objects the row held (floats bit for bit). The
writers stream row by row, so writing 100,000 rows holds one row's text at a time.
"""
from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

_INT64 = 2**63


def _column(values: list[Any]) -> np.ndarray:
    """A column holding ``values`` exactly: float64 / int64 / bool when every value is of that very
    type (``.item()`` gives the same Python object back), else references (dtype object)."""
    types = {type(v) for v in values}
    if types == {float}:
        return np.array(values, dtype=np.float64)
    if types == {bool}:
        return np.array(values, dtype=np.bool_)
    if types == {int} and all(-_INT64 <= v < _INT64 for v in values):
        return np.array(values, dtype=np.int64)
    col = np.empty(len(values), dtype=object)
    for i, v in enumerate(values):
        col[i] = v
    return col


class _Block:
    """Consecutive rows with the same keys (in the same order), as columns."""

    __slots__ = ("keys", "cols", "n")

    def __init__(self, keys: tuple[str, ...], rows: list[Mapping[str, Any]]) -> None:
        self.keys = keys
        self.n = len(rows)
        self.cols = {k: _column([r[k] for r in rows]) for k in keys}

    def __getstate__(self) -> tuple[Any, ...]:
        return self.keys, self.cols, self.n

    def __setstate__(self, state: tuple[Any, ...]) -> None:
        self.keys, self.cols, self.n = state


class Row(Mapping[str, Any]):
    """One row of a :class:`RowTable`: a read-only mapping (pickles, and prints, as a dict)."""

    __slots__ = ("_b", "_i")

    def __init__(self, block: _Block, i: int) -> None:
        self._b, self._i = block, i

    def __getitem__(self, key: str) -> Any:
        return self._b.cols[key].item(self._i)

    def __iter__(self) -> Iterator[str]:
        return iter(self._b.keys)

    def __len__(self) -> int:
        return len(self._b.keys)

    def __contains__(self, key: object) -> bool:
        return key in self._b.cols

    def __repr__(self) -> str:
        return repr(dict(self))

    def __reduce__(self) -> tuple[Any, ...]:
        return dict, (dict(self),)


class RowTable(Sequence[Any]):
    """A sweep's rows as compact columns (see the module docstring); ``rows[i]`` is a :class:`Row`."""

    def __init__(self, rows: Iterable[Mapping[str, Any]] = ()) -> None:
        self._blocks: list[_Block] = []
        self._starts: list[int] = []
        self._n = 0
        self.extend(rows)

    def extend(self, rows: Iterable[Mapping[str, Any]]) -> None:
        """Append rows (a :class:`RowTable`'s blocks are taken as they are)."""
        if isinstance(rows, RowTable):
            for b in rows._blocks:
                self._add(b)
            return
        group: list[Mapping[str, Any]] = []
        keys: tuple[str, ...] | None = None
        for r in rows:
            k = tuple(r)
            if keys is not None and k != keys:
                self._add(_Block(keys, group))
                group = []
            keys = k
            group.append(r)
        if keys is not None:
            self._add(_Block(keys, group))

    def _add(self, block: _Block) -> None:
        if block.n:
            self._blocks.append(block)
            self._starts.append(self._n)
            self._n += block.n

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self._n))]
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError("row index out of range")
        import bisect

        b = bisect.bisect_right(self._starts, i) - 1
        return Row(self._blocks[b], i - self._starts[b])

    def __iter__(self) -> Iterator[Row]:
        for b in self._blocks:
            for i in range(b.n):
                yield Row(b, i)

    def columns(self) -> list[str]:
        """Every key in first-seen order (as :func:`columns` of the rows)."""
        return list(dict.fromkeys(k for b in self._blocks for k in b.keys))

    def sorted(self) -> RowTable:
        """The rows ordered by ``(index, controller_index)`` (stable). Blocks that each hold a sorted
        run of their own range (the batched path's chunks) are only reordered, not rebuilt."""
        def first(b: _Block) -> tuple[int, int]:
            return int(b.cols["index"][0]), int(b.cols["controller_index"][0])

        def key_array(b: _Block) -> np.ndarray:
            return np.stack([np.asarray(b.cols["index"], dtype=np.int64),
                             np.asarray(b.cols["controller_index"], dtype=np.int64)], axis=1)

        blocks = sorted(self._blocks, key=first)
        last: tuple[int, int] | None = None
        ok = True
        for b in blocks:
            k = key_array(b)
            if b.n > 1 and not bool(np.all((k[1:, 0] > k[:-1, 0]) | ((k[1:, 0] == k[:-1, 0]) & (k[1:, 1] >= k[:-1, 1])))):
                ok = False
                break
            if last is not None and tuple(k[0]) < last:
                ok = False
                break
            last = (int(k[-1, 0]), int(k[-1, 1]))
        out = RowTable()
        if ok:
            for b in blocks:
                out._add(b)
        else:  # interleaved blocks: rebuild in order (rows as dicts, one pass)
            out.extend(sorted((dict(r) for r in self), key=lambda r: (r["index"], r["controller_index"])))
        return out


def jsonable(v: Any) -> Any:
    # JSON has no NaN: undefined metrics (e.g. touchdown speed of a flight that never touched) are null.
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    return v


def columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    if isinstance(rows, RowTable):
        return rows.columns()
    return list(dict.fromkeys(k for r in rows for k in r))


def write_csv(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """One line per flight and controller; floats with ``repr`` precision so a re-read is exact."""
    cols = columns(rows)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})
    return path


def write_json(obj: Any, path: Path) -> Path:
    path.write_text(json.dumps(jsonable(obj), indent=1, allow_nan=False) + "\n")
    return path


def write_rows_json(rows: Iterable[Mapping[str, Any]], path: Path) -> Path:
    """The rows as a JSON list, the same text as :func:`write_json` of ``list(rows)``, written row
    by row (one row's text in memory at a time)."""
    with open(path, "w") as f:
        n = 0
        for r in rows:
            text = json.dumps(jsonable(dict(r)), indent=1, allow_nan=False)
            f.write(("[\n" if n == 0 else ",\n") + "\n".join(" " + line for line in text.split("\n")))
            n += 1
        f.write("[]\n" if n == 0 else "\n]\n")
    return path


def write_parquet(rows: Sequence[dict[str, Any]], path: Path) -> Path | None:
    """Parquet via pyarrow if it is installed; None (and nothing written) otherwise."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return None
    cols = columns(rows)
    table = pa.table({c: [r.get(c) for r in rows] for c in cols})
    pq.write_table(table, path)
    return path


def write_all(out: Path, rows: Sequence[dict[str, Any]], summary: dict[str, Any], summary_text: str) -> list[Path]:
    """``flights.csv``, ``flights.json``, ``flights.parquet`` (optional), ``summary.json``, ``summary.txt``."""
    out.mkdir(parents=True, exist_ok=True)
    written = [write_csv(rows, out / "flights.csv"), write_rows_json(rows, out / "flights.json")]
    pq = write_parquet(rows, out / "flights.parquet")
    if pq is not None:
        written.append(pq)
    written.append(write_json(summary, out / "summary.json"))
    (out / "summary.txt").write_text(summary_text + "\n")
    written.append(out / "summary.txt")
    return written
