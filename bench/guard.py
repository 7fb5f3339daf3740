"""Regression guard: the compiled paths of the working tree timed against a git revision, side by side.

Run it before resolving any change to ``lander_sim/fast/``, the compiled controllers
(``lander_autopilot/controllers/compiled.py``) or the batched sweep (``lander_tools/sweep/batched*``)::

    ./dev bench guard --against origin/main [--runs 5] [--figures kernel,closed_loop] [--quick]

The revision's tree is exported (``git archive``) into a temporary directory, and so is the working
tree as it is (tracked and untracked files, edits included), so both are fresh directories that
differ in their code only. Each run is one fresh
interpreter per tree, the two trees alternating (A B, then B A, ...), every interpreter with the
tree's directory first on ``PYTHONPATH`` and the tree's packages imported from it before anything
else (checked: every ``lander_*`` module's file must lie in that tree). Both trees are timed by the
same probes, the functions of *this* tree's benchmarks (bench/speed.py, bench/ceiling.py,
bench/ceiling_loop.py, bench/closed_loop.py, bench/integrators.py), so only the product code differs. numba caches its
machine code beside each source file, so the two trees never share cache entries; the first run of
each exported tree compiles, outside the timed windows. The table gives, per figure, the median of
each tree over the runs, the ratio of the medians A/B and the range of the run-by-run ratios.
``ceiling`` and ``loop_ceiling`` are the fused loops of bench/ceiling.py and bench/ceiling_loop.py,
the same code in both trees: their ratios show what the machine's noise alone does to a ratio; the
last rows are each tree's figure over its ceiling in the same run. A figure a tree cannot run (a revision without the batched
sweep) is ``-``, with the reason below the table.

    python bench/guard.py --against REV [--runs N] [--figures a,b] [--quick] [--json FILE]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import _common as C

#: The packages a tree provides (imported from the tree under test before any probe runs).
PACKAGES = ("lander_yaml", "lander_sim", "lander_autopilot", "lander_tools")


@dataclass(frozen=True)
class Figure:
    key: str
    label: str
    unit: str


FIGURES = (
    Figure("kernel", "compiled Verlet kernel, hover (bench/speed.py)", "steps/s"),
    Figure("ceiling", "fused ceiling loop, hover (bench/ceiling.py; same code in A and B)", "steps/s"),
    Figure("closed_loop", "compiled closed loop, hover-canted + combined, 1 thread (bench/closed_loop.py)", "loops/s"),
    Figure("loop_ceiling", "fused ceiling of that loop (bench/ceiling_loop.py; same code in A and B)", "loops/s"),
    Figure("batched", "batched sweep hover-robustness, 1 worker, per CPU second (bench/closed_loop.py)", "flights/s"),
    Figure("integrators", "compiled DOP853, one Kepler orbit at tol 1e-10 (bench/integrators.py)", "evals/s"),
)
#: Ratios of two figures of the same run of the same tree (noise of the machine largely cancels).
DERIVED = (("kernel/ceiling", "kernel", "ceiling"), ("closed loop/its ceiling", "closed_loop", "loop_ceiling"))


# --- the probes (run inside the interpreter of the tree under test) ------------------------------


def _kernel_and_ceiling(quick: bool) -> dict[str, float]:
    import ceiling
    import numpy as np

    from lander_sim import fast

    sim = __import__("speed").hover_sim()
    fl = fast.FastLander(sim.dynamics)
    c = ceiling.constants(fl, np.asarray(ceiling.THROTTLES), np.asarray(ceiling.WIND))
    r = ceiling.time_side_by_side(fl, sim.y.copy(), c, 60 if quick else 300, 3)
    return {"kernel": r["kernel_steps_per_s"], "ceiling": r["ceiling_steps_per_s"]}


def _closed_loop(quick: bool) -> dict[str, float]:
    import ceiling_loop

    r = ceiling_loop.time_side_by_side(ceiling_loop.flight(), 60 if quick else 300, 3)
    return {"closed_loop": r["compiled_loops_per_s"], "loop_ceiling": r["ceiling_loops_per_s"]}


def _batched(quick: bool) -> dict[str, float]:
    import closed_loop

    return {"batched": closed_loop.batched_cpu_rate(100 if quick else 400)}


def _integrators(quick: bool) -> dict[str, float]:
    import integrators

    return {"integrators": integrators.compiled_kepler_rate(quick)}


PROBES: dict[str, Callable[[bool], dict[str, float]]] = {
    "kernel": _kernel_and_ceiling, "ceiling": _kernel_and_ceiling, "closed_loop": _closed_loop, "loop_ceiling": _closed_loop,
    "batched": _batched, "integrators": _integrators,
}


def probe(keys: Sequence[str], quick: bool) -> dict[str, object]:
    """Measure ``keys`` in this interpreter: ``{key: value}`` and ``errors: {key: last line of the error}``."""
    out: dict[str, object] = {}
    errors: dict[str, str] = {}
    done: set[Callable[[bool], dict[str, float]]] = set()
    for key in keys:
        fn = PROBES[key]
        if fn in done:
            continue
        done.add(fn)
        try:
            out.update(fn(quick))
        except Exception as exc:  # noqa: BLE001 - a tree without that path: reported, not fatal
            errors[key] = f"{type(exc).__name__}: {exc}".splitlines()[0][:160]
    out["errors"] = errors
    return out


_RUNNER = """
import json, sys
root, bench, keys, quick, out = sys.argv[1:]
sys.path.insert(0, root)
import importlib
from pathlib import Path
for name in {packages!r}:
    if (Path(root) / name / "__init__.py").is_file():
        importlib.import_module(name)
sys.path.insert(1, bench)
import guard
res = guard.probe(keys.split(","), quick == "1")
strays = sorted(m for m, mod in list(sys.modules.items()) if m.split(".")[0] in {packages!r}
                and getattr(mod, "__file__", None) and not Path(mod.__file__).resolve().is_relative_to(Path(root).resolve()))
res["strays"] = strays
res["lander_kernel_file"] = getattr(sys.modules.get("lander_sim.fast.lander_kernel"), "__file__", None)
Path(out).write_text(json.dumps(res))
"""


def _run_tree(root: Path, keys: Sequence[str], quick: bool, out: Path) -> dict[str, object]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(root), *filter(None, [env.get("PYTHONPATH")])])
    code = _RUNNER.format(packages=PACKAGES)
    proc = subprocess.run([sys.executable, "-c", code, str(root), str(Path(__file__).resolve().parent), ",".join(keys),
                           "1" if quick else "0", str(out)], env=env, capture_output=True, text=True, cwd=str(root))
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"probe in {root} failed: {tail}")
    res: dict[str, object] = json.loads(out.read_text())
    if res["strays"]:
        raise RuntimeError(f"probe in {root} imported modules from elsewhere: {res['strays'][:5]}")
    return res


# --- the table (pure) -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    label: str
    unit: str
    median_a: float
    median_b: float
    ratio: float  # median_a / median_b
    ratio_low: float  # smallest run-by-run ratio A_i / B_i
    ratio_high: float


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return statistics.median(finite) if finite else math.nan


def summarise(a: Mapping[str, Sequence[float]], b: Mapping[str, Sequence[float]],
              figures: Sequence[Figure] = FIGURES, derived: Sequence[tuple[str, str, str]] = DERIVED) -> list[Row]:
    """Rows of the guard's table from each tree's runs (``{figure key: [value per run]}``, NaN: not
    measured). The run-by-run ratios pair the i-th run of A with the i-th of B (taken next to each
    other); ``derived`` rows ``(label, num, den)`` are per-run ratios num/den within one tree."""
    def ratio(x: float, y: float) -> float:
        return x / y if math.isfinite(x) and math.isfinite(y) and y != 0.0 else math.nan

    def row(label: str, unit: str, xa: Sequence[float], xb: Sequence[float]) -> Row:
        ma, mb = _median(xa), _median(xb)
        pairs = [ratio(x, y) for x, y in zip(xa, xb, strict=False)]
        pairs = [p for p in pairs if math.isfinite(p)]
        return Row(label, unit, ma, mb, ratio(ma, mb), min(pairs, default=math.nan), max(pairs, default=math.nan))

    rows = [row(f.label, f.unit, a.get(f.key, []), b.get(f.key, [])) for f in figures if f.key in a or f.key in b]
    for label, num, den in derived:
        if num in a and den in a:
            per_a = [ratio(x, y) for x, y in zip(a[num], a[den], strict=False)]
            per_b = [ratio(x, y) for x, y in zip(b.get(num, []), b.get(den, []), strict=False)]
            rows.append(row(label, "ratio", per_a, per_b))
    return rows


def format_table(rows: Sequence[Row], name_a: str, name_b: str, runs: int) -> str:
    def num(v: float) -> str:
        if not math.isfinite(v):
            return "-"
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:,.0f}"

    body = [[r.label, r.unit, num(r.median_a), num(r.median_b), num(r.ratio),
             "-" if not math.isfinite(r.ratio_low) else f"{r.ratio_low:.3f}..{r.ratio_high:.3f}"] for r in rows]
    header = ["figure", "unit", "median A", "median B", "A/B", "A/B per run"]
    w = [max(len(h), *(len(r[i]) for r in body)) if body else len(h) for i, h in enumerate(header)]
    def line(cells: Sequence[str]) -> str:  # the figure's name left-aligned, the numbers right-aligned
        return "  ".join(c.ljust(w[i]) if i < 2 else c.rjust(w[i]) for i, c in enumerate(cells))
    out = [f"A = {name_a}, B = {name_b}: medians of {runs} runs each, alternating", line(header), "-" * len(line(header))]
    return "\n".join(out + [line(r) for r in body]) + "\n"


# --- the command ----------------------------------------------------------------------------------


def export_revision(rev: str, repo: Path, dest: Path) -> str:
    """Write ``rev``'s tree into ``dest`` (git archive); returns the revision's full hash."""
    full = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=repo, capture_output=True,
                          text=True, check=True).stdout.strip()
    archive = dest.parent / "tree.tar"
    with archive.open("wb") as f:
        subprocess.run(["git", "archive", "--format=tar", full], cwd=repo, stdout=f, check=True)
    with tarfile.open(archive) as t:
        t.extractall(dest, filter="data")
    archive.unlink()
    return full


def export_working_tree(repo: Path, dest: Path) -> None:
    """Copy the working tree's files as they are now (tracked and untracked, not ignored, edits
    included) into ``dest``: A then lives in a fresh directory as B does, so the two trees differ
    in their code only (the checkout itself, with its .venv and caches, timed measurably slower in
    the batched sweep's set-up than an export of the very same commit)."""
    names = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=repo,
                           capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, names):
        src = repo / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    p = C.parser(__doc__.splitlines()[0])
    p.add_argument("--against", metavar="REV", required=True, help="git revision to time against (B)")
    p.add_argument("--runs", type=int, default=5, help="runs per tree (default 5; medians over them)")
    p.add_argument("--figures", default=",".join(f.key for f in FIGURES),
                   help=f"comma-separated subset of {', '.join(f.key for f in FIGURES)}")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    keys = [k.strip() for k in args.figures.split(",") if k.strip()]
    unknown = [k for k in keys if k not in PROBES]
    if unknown or args.runs < 1:
        raise SystemExit(f"guard: unknown figure(s) {unknown} (choose from {', '.join(PROBES)}) or --runs < 1")
    with tempfile.TemporaryDirectory(prefix="lander-guard-") as tmp:
        tree_a, tree_b = Path(tmp) / "working", Path(tmp) / "tree"
        tree_a.mkdir()
        tree_b.mkdir()
        export_working_tree(C.ROOT, tree_a)
        full = export_revision(args.against, C.ROOT, tree_b)
        name_a, name_b = f"working tree {C.ROOT}", f"{args.against} ({full[:10]})"
        runs: dict[str, dict[str, list[float]]] = {"A": {k: [] for k in keys}, "B": {k: [] for k in keys}}
        errors: dict[str, dict[str, str]] = {"A": {}, "B": {}}
        kernel_files: dict[str, object] = {}
        load0, t0 = os.getloadavg()[0], time.perf_counter()
        for i in range(args.runs):
            order = ("A", "B") if i % 2 == 0 else ("B", "A")
            for side in order:
                res = _run_tree(tree_a if side == "A" else tree_b, keys, args.quick, Path(tmp) / f"{side}{i}.json")
                kernel_files[side] = res["lander_kernel_file"]
                errors[side].update(res["errors"])  # type: ignore[arg-type]
                for k in keys:
                    v = res.get(k)
                    runs[side][k].append(float(v) if isinstance(v, (int, float)) else math.nan)
            print(f"run {i + 1}/{args.runs} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
        rows = summarise(runs["A"], runs["B"])
    print(format_table(rows, name_a, name_b, args.runs))
    print(f"kernel imported from: A {kernel_files.get('A')}, B {kernel_files.get('B')}")
    print(f"load average {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} cores")
    for side, errs in errors.items():
        for k, why in errs.items():
            print(f"{side}: {k} not measured: {why}")
    C.write_json(args.json, {"against": args.against, "commit": full, "runs": runs, "errors": errors,
                             "rows": [r.__dict__ for r in rows]})
    return 0


if __name__ == "__main__":
    sys.exit(main())
