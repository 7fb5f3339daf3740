"""Write a sweep's results: per-flight table (CSV, JSON, Parquet when pyarrow is installed) and summary."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any, Sequence


def jsonable(v: Any) -> Any:
    # JSON has no NaN: undefined metrics (e.g. touchdown speed of a flight that never touched) are null.
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    return v


def columns(rows: Sequence[dict[str, Any]]) -> list[str]:
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
    written = [write_csv(rows, out / "flights.csv"), write_json(list(rows), out / "flights.json")]
    pq = write_parquet(rows, out / "flights.parquet")
    if pq is not None:
        written.append(pq)
    written.append(write_json(summary, out / "summary.json"))
    (out / "summary.txt").write_text(summary_text + "\n")
    written.append(out / "summary.txt")
    return written
