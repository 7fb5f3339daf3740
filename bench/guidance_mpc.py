"""The de-orbit MPC's per-period solve and the MPC sweeps' wall time per flight: the working tree
beside a git revision, flown side by side in one run.

For the first ``--flights`` cases of each de-orbit sweep (sweeps/deorbit-200km.yaml,
sweeps/deorbit.yaml) the MPC law's flight is flown whole by the sweep's own per-flight path
(:func:`lander_tools.sweep.flight.fly_case`, the loop every sweep worker runs), once with each
tree, in a fresh interpreter per tree and flight with that tree's packages first on the path
(checked: no ``lander_*`` module comes from elsewhere). The trees alternate flight by flight (A B,
then B A), so a change in the machine's load falls on both; each tree first flies one flight
untimed (numba compiles into the tree's own cache on first use). The revision is exported with
``git archive`` and the working tree copied as it is (bench/guard.py's exports), so the two differ
in their code only; the probe is this file's :func:`probe` in both.

Per flight it keeps:

* every period's MPC solve time (``MpcStats.solve_times``: the programme's solve from its
  parameters' values, as the law's diagnostics time it) and the whole ``DescentMpc.command``
  call's (the drag's linearisation and the parameters' set-up too);
* the reference's solve time at the handover (``mpc_reference_time``, the law's diagnostics);
* the fuel from the handover to the band at rest (``fuel_ratio`` x ``powered_optimum``) and both
  yardsticks (``fuel_ratio``, ``fuel_ratio_balanced``; the sweeps' acceptance is 1.05 x on each);
* the whole command's CPU time (``time.thread_time``: what the load of the machine does not stretch);
* the flight's wall time (what a sweep worker spends on it: the flight, the reference and the two
  yardstick solves, ``powered_optimum``, timed), that time less the reference's, and less the
  yardsticks' too (the fuel-optimal solves left: what the rest of the flight costs);
* the flight's CPU time (``time.process_time``: every thread of the process, which the machine's
  load stretches far less than the wall time);
* the flown throttles of every period, to compare the trees' flights (largest difference over the
  powered descent and after it);
* in the working tree, beside each flown solve, the same programme solved again through cvxpy's
  ``Problem.solve`` (a fresh Clarabel solver, and cvxpy's kept one updated in place), timed, with
  its plan's largest difference from the flown one; the time spent on them is taken off the
  flight's wall time and its command times.

The table has a row a flight and tree, then a row per sweep and tree over all its flights' periods
(pooled percentiles), then the ratios B / A of those figures measured in this run.

    ./dev exec python bench/guidance_mpc.py [--against 9cab8fa] [--flights 4] [--specs deorbit-200km,deorbit] [--json FILE]
    ./dev exec python bench/guidance_mpc.py --quick      # one flight of the 200 km sweep a tree (~4 min)

:func:`rows` returns the table's rows (dicts) for a composed benchmark.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import _common as C
import guard
import numpy as np

#: The revision timed against by default: the receding-horizon programme compiled by cvxpy each period.
AGAINST = "9cab8fa"
SPECS = ("deorbit-200km", "deorbit")
#: The MPC law's label in the de-orbit sweeps' specs.
MPC_LABEL = "mpc"

# --- the probe (run inside the interpreter of the tree under test) ------------------------------


def probe(spec_path: str, index: int) -> dict[str, Any]:
    """Fly case ``index`` of the sweep ``spec_path`` with its MPC law (fly_case), timed; the figures
    listed in the module docstring, as plain lists and floats (JSON)."""
    from lander_autopilot.guidance.descent_mpc import DescentMpc
    from lander_tools.sweep import flight
    from lander_tools.sweep.spec import load_spec

    spec = load_spec(spec_path)
    ci = [c.label for c in spec.controllers].index(MPC_LABEL)
    # The sweep designs a law once per process (its cache): design it before the timed flight, and
    # keep the very object fly_case then resets and flies, to read its MPC after the flight.
    ctrl = flight.case_controller(spec, ci, flight.nominal_scene(spec).vehicle)
    command_times: list[float] = []
    command = DescentMpc.command
    alternatives = _beside_each_solve()

    command_cpu: list[float] = []
    yardstick = [0.0]
    optimum = flight.powered_optimum

    def timed_command(self: Any, *args: Any, **kwargs: Any) -> Any:
        t0, c0, extra, extra_cpu = time.perf_counter(), time.thread_time(), alternatives["extra"], alternatives["extra_cpu"]
        n = len(self.stats.solve_times)
        out = command(self, *args, **kwargs)
        beside = alternatives["extra"] - extra
        command_times.append(time.perf_counter() - t0 - beside)
        if len(self.stats.solve_times) > n:  # the law timed its solve with the solves beside it: less them
            self.stats.solve_times[-1] -= beside
        command_cpu.append(time.thread_time() - c0 - (alternatives["extra_cpu"] - extra_cpu))
        return out

    def timed_optimum(*args: Any, **kwargs: Any) -> float:
        t0 = time.perf_counter()
        value = optimum(*args, **kwargs)
        yardstick[0] += time.perf_counter() - t0
        return value

    DescentMpc.command = timed_command  # type: ignore[method-assign]
    flight.powered_optimum = timed_optimum
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        result = flight.fly_case(spec, ci, index, record=True)
        wall = time.perf_counter() - t0 - alternatives["extra"]  # less the solves beside the flown ones
        cpu = time.process_time() - c0 - alternatives["extra_cpu"]
    finally:
        DescentMpc.command = command  # type: ignore[method-assign]
        flight.powered_optimum = optimum
        alternatives.pop("restore")()  # type: ignore[operator]
    row = result.row
    mpc = ctrl.mpc
    diag = ctrl.diagnostics()
    traj = result.trajectory
    return {
        "wall": wall, "cpu": cpu, "reference_time": float(diag.get("mpc_reference_time", math.nan)), "yardstick_time": yardstick[0],
        "solve_times": list(mpc.stats.solve_times) if mpc is not None else [], "command_times": command_times,
        "command_cpu": command_cpu,
        "failures": int(mpc.stats.failures) if mpc is not None else -1,
        "fuel_ratio": float(row["fuel_ratio"]), "fuel_ratio_balanced": float(row["fuel_ratio_balanced"]),
        "fuel": float(row["fuel_ratio"]) * float(row["powered_optimum"]),
        "throttles": traj.throttles.tolist() if traj is not None else [],
        "t": traj.t.tolist() if traj is not None else [],
        "alternatives": alternatives,
    }


def _beside_each_solve() -> dict[str, Any]:
    """In a tree whose MPC solves through :class:`~lander_autopilot.guidance.conic_program.ConicProgram`:
    after each period's solve (the flown one, untouched) the very same programme is solved again
    through cvxpy's ``Problem.solve`` with Clarabel, with a fresh solver (``warm_start=False``) and
    with cvxpy's kept one updated in place (its default), each timed, with the largest difference of
    any of its plan's variables from the flown solve's (positions in m, velocities in m/s, thrust
    accelerations in m/s^2). Empty lists in a tree without it."""
    out: dict[str, Any] = {"cvxpy_fresh": [], "cvxpy_kept": [], "cvxpy_fresh_gap": 0.0, "cvxpy_kept_gap": 0.0,
                           "extra": 0.0, "extra_cpu": 0.0}  # [s] wall and CPU time spent beside the flown solves
    try:
        from lander_autopilot.guidance.conic_program import ConicProgram
    except ImportError:
        out["restore"] = lambda: None
        return out
    import warnings

    import cvxpy as cp

    solve = ConicProgram.solve

    def solve_and_beside(self: Any) -> bool:
        ok = solve(self)
        begin, begin_cpu = time.perf_counter(), time.thread_time()
        self.store()
        for key, warm in (("cvxpy_fresh", False), ("cvxpy_kept", True)):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                self.problem.solve(solver=cp.CLARABEL, warm_start=warm)
            out[key].append(time.perf_counter() - t0)
            if ok and self.problem.status in ("optimal", "optimal_inaccurate"):
                gap = max(float(np.max(np.abs(self.value(v) - v.value))) for v in self.problem.variables())
                out[key + "_gap"] = max(out[key + "_gap"], gap)
        out["extra"] += time.perf_counter() - begin
        out["extra_cpu"] += time.thread_time() - begin_cpu
        return ok

    ConicProgram.solve = solve_and_beside  # type: ignore[method-assign]

    def restore() -> None:
        ConicProgram.solve = solve  # type: ignore[method-assign]

    out["restore"] = restore
    return out


_RUNNER = """
import json, sys
root, bench, spec, index, out = sys.argv[1:]
sys.path.insert(0, root)
import importlib
from pathlib import Path
for name in {packages!r}:
    if (Path(root) / name / "__init__.py").is_file():
        importlib.import_module(name)
sys.path.insert(1, bench)
import guidance_mpc
res = guidance_mpc.probe(spec, int(index))
res["strays"] = sorted(m for m, mod in list(sys.modules.items()) if m.split(".")[0] in {packages!r}
                       and getattr(mod, "__file__", None) and not Path(mod.__file__).resolve().is_relative_to(Path(root).resolve()))
Path(out).write_text(json.dumps(res))
"""


def _run(root: Path, spec: str, index: int, out: Path) -> dict[str, Any]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(root), *filter(None, [env.get("PYTHONPATH")])])
    proc = subprocess.run([sys.executable, "-c", _RUNNER.format(packages=guard.PACKAGES), str(root),
                           str(Path(__file__).resolve().parent), str(root / "sweeps" / f"{spec}.yaml"), str(index), str(out)],
                          env=env, capture_output=True, text=True, cwd=str(root))
    if proc.returncode != 0:
        raise RuntimeError(f"probe in {root} failed: {(proc.stderr.strip().splitlines() or ['(no output)'])[-1]}")
    res: dict[str, Any] = json.loads(out.read_text())
    if res["strays"]:
        raise RuntimeError(f"probe in {root} imported modules from elsewhere: {res['strays'][:5]}")
    return res


# --- the rows (pure) ------------------------------------------------------------------------------


def _ms(values: Sequence[float]) -> tuple[float, float, float]:
    if not values:
        return math.nan, math.nan, math.nan
    x = 1e3 * np.asarray(values)
    return float(np.median(x)), float(np.percentile(x, 99)), float(x.max())


def _throttle_gap(a: dict[str, Any], b: dict[str, Any]) -> float:
    """Largest difference of the two flights' throttles over the periods both flew [-]."""
    n = min(len(a["throttles"]), len(b["throttles"]))
    if n == 0:
        return math.nan
    return float(np.max(np.abs(np.asarray(a["throttles"][:n]) - np.asarray(b["throttles"][:n]))))


def summarise(spec: str, tree: str, case: str, flights: Sequence[dict[str, Any]], gap: float = math.nan) -> dict[str, Any]:
    """One row of the table: a flight (``case`` its index) or, with several, a sweep's pooled periods."""
    solve = [t for f in flights for t in f["solve_times"]]
    command = [t for f in flights for t in f["command_times"]]
    med, p99, top = _ms(solve)
    cmed, cp99, ctop = _ms(command)
    cpu_med, cpu_p99, _cpu_top = _ms([t for f in flights for t in f["command_cpu"]])
    def mean(key: str) -> float:
        return float(np.mean([f[key] for f in flights]))
    def worst(key: str) -> float:
        return float(np.max([f[key] for f in flights]))
    return {"spec": spec, "tree": tree, "case": case, "periods": len(solve),
            "solve_median_ms": med, "solve_p99_ms": p99, "solve_max_ms": top,
            "command_median_ms": cmed, "command_p99_ms": cp99, "command_max_ms": ctop,
            "command_cpu_median_ms": cpu_med, "command_cpu_p99_ms": cpu_p99,
            "failures": int(sum(f["failures"] for f in flights)),
            "fuel_kg": mean("fuel"), "fuel_ratio": worst("fuel_ratio"), "fuel_ratio_balanced": worst("fuel_ratio_balanced"),
            "wall_s": mean("wall"), "cpu_s": mean("cpu"), "reference_s": mean("reference_time"),
            "yardstick_s": mean("yardstick_time"),
            "wall_less_reference_s": float(np.mean([f["wall"] - f["reference_time"] for f in flights])),
            "wall_less_guidance_s": float(np.mean([f["wall"] - f["reference_time"] - f["yardstick_time"] for f in flights])),
            "throttle_gap": gap, "plan_gap": math.nan}


def beside(spec: str, label: str, flights: Sequence[dict[str, Any]], key: str) -> dict[str, Any]:
    """The pooled row of one of the calls timed beside A's flown solves (:func:`_beside_each_solve`)."""
    med, p99, top = _ms([t for f in flights for t in f["alternatives"][key]])
    nan = math.nan
    return {"spec": spec, "tree": label, "case": "all", "periods": sum(len(f["alternatives"][key]) for f in flights),
            "solve_median_ms": med, "solve_p99_ms": p99, "solve_max_ms": top,
            "command_median_ms": nan, "command_p99_ms": nan, "command_max_ms": nan, "failures": "",
            "command_cpu_median_ms": nan, "command_cpu_p99_ms": nan,
            "fuel_kg": nan, "fuel_ratio": nan, "fuel_ratio_balanced": nan, "wall_s": nan, "cpu_s": nan, "reference_s": nan,
            "yardstick_s": nan, "wall_less_reference_s": nan, "wall_less_guidance_s": nan, "throttle_gap": nan,
            "plan_gap": max((f["alternatives"][key + "_gap"] for f in flights), default=nan)}


def rows(against: str = AGAINST, specs: Sequence[str] = SPECS, flights: int = 4,
         log: Any = None) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Fly the cases with both trees (A = the working tree, B = ``against``); returns the table's
    rows (flight rows, then per sweep and tree the pooled row) and the run's facts (revision, load)."""
    with tempfile.TemporaryDirectory(prefix="lander-guidance-mpc-") as tmp:
        tree_a, tree_b = Path(tmp) / "working", Path(tmp) / "tree"
        tree_a.mkdir()
        tree_b.mkdir()
        guard.export_working_tree(C.ROOT, tree_a)
        full = guard.export_revision(against, C.ROOT, tree_b)
        # numba compiles the simulation's kernel and the entry predictor into each tree's own cache
        # on their first use: one untimed flight a tree first, so that no timed flight pays for it
        for side, root in (("A", tree_a), ("B", tree_b)):
            _run(root, specs[0], 0, Path(tmp) / f"warm-{side}.json")
        if log is not None:
            print("both trees warmed up (a flight each, untimed)", file=log)
        load0, t0 = os.getloadavg()[0], time.perf_counter()
        flown: dict[tuple[str, str], list[dict[str, Any]]] = {}
        n = 0
        for spec in specs:
            for index in range(flights):
                order = ("A", "B") if n % 2 == 0 else ("B", "A")
                n += 1
                for side in order:
                    res = _run(tree_a if side == "A" else tree_b, spec, index, Path(tmp) / f"{side}-{spec}-{index}.json")
                    flown.setdefault((spec, side), []).append(res)
                if log is not None:
                    print(f"{spec} case {index} flown by both trees ({time.perf_counter() - t0:.0f} s)", file=log)
        load1 = os.getloadavg()[0]
    out: list[dict[str, Any]] = []
    for spec in specs:
        for side in ("B", "A"):
            for index, f in enumerate(flown[(spec, side)]):
                gap = _throttle_gap(f, flown[(spec, "B")][index]) if side == "A" else math.nan
                out.append(summarise(spec, side, str(index), [f], gap))
        for side in ("B", "A"):
            out.append(summarise(spec, side, "all", flown[(spec, side)]))
        for key, label in (("cvxpy_fresh", "A, cvxpy fresh"), ("cvxpy_kept", "A, cvxpy kept")):
            out.append(beside(spec, label, flown[(spec, "A")], key))
    facts = {"against": against, "commit": full, "load_start": load0, "load_end": load1, "cores": os.cpu_count(),
             "wall": time.perf_counter() - t0}
    return out, facts


COLUMNS = (("spec", "spec"), ("tree", "tree"), ("case", "case"), ("periods", "periods"),
           ("solve_median_ms", "solve med ms"), ("solve_p99_ms", "p99"), ("solve_max_ms", "max"),
           ("command_p99_ms", "command p99 ms"), ("command_max_ms", "max"),
           ("command_cpu_median_ms", "CPU med ms"), ("command_cpu_p99_ms", "p99"), ("failures", "fail"),
           ("fuel_kg", "fuel kg"), ("fuel_ratio", "fuel_ratio"), ("fuel_ratio_balanced", "balanced"),
           ("throttle_gap", "|dthrottle| vs B"), ("plan_gap", "plan gap"), ("wall_s", "wall s"), ("cpu_s", "CPU s"), ("reference_s", "ref s"),
           ("yardstick_s", "yardst. s"), ("wall_less_reference_s", "wall-ref s"), ("wall_less_guidance_s", "-yardst. s"))
RATIOS = ("solve_median_ms", "solve_p99_ms", "solve_max_ms", "command_p99_ms", "command_max_ms", "command_cpu_median_ms",
          "command_cpu_p99_ms", "wall_s", "cpu_s", "wall_less_reference_s", "wall_less_guidance_s")


#: Columns printed finer than the table's three figures: the yardsticks to 1e-4 (the acceptance is
#: 1.05), the fuel to 10 g, the throttles' difference in powers of ten.
FORMATS = {"fuel_ratio": "{:.4f}", "fuel_ratio_balanced": "{:.4f}", "fuel_kg": "{:.2f}", "throttle_gap": "{:.1e}",
           "plan_gap": "{:.1e}"}


def _cell(key: str, value: Any) -> Any:
    if key in FORMATS and isinstance(value, float) and math.isfinite(value):
        return FORMATS[key].format(value)
    return value


def format_table(table: Sequence[dict[str, Any]], facts: dict[str, Any]) -> str:
    body = [[_cell(k, r[k]) for k, _ in COLUMNS] for r in table]
    for spec in dict.fromkeys(r["spec"] for r in table):
        a = next(r for r in table if r["spec"] == spec and r["tree"] == "A" and r["case"] == "all")
        for label in ("B", "A, cvxpy fresh", "A, cvxpy kept"):
            b = next(r for r in table if r["spec"] == spec and r["tree"] == label and r["case"] == "all")
            body.append([spec, f"{label} / A", "all", ""] + [b[k] / a[k] if k in RATIOS and a[k] else ""
                                                          for k, _ in COLUMNS[4:]])
    title = (f"A = working tree, B = {facts['against']} ({facts['commit'][:10]}): the MPC law's flights of each sweep's first "
             f"cases (fly_case), a fresh interpreter per tree and flight; solve and command times per period; "
             f"fuel to the band at rest; fuel_ratio, balanced: the yardsticks (acceptance 1.05); 'all': pooled "
             f"periods, fuel and wall means, ratios' worst. 'A, cvxpy fresh' and 'A, cvxpy kept': the same "
             f"programmes as A's flown solves, solved again beside each through cvxpy's Problem.solve (a fresh Clarabel "
             f"solver; cvxpy's kept one updated), 'plan gap' their plans' largest difference from A's (m, m/s, m/s^2)")
    text = C.table(title, [h for _, h in COLUMNS], body)
    return text + (f"load average {facts['load_start']:.1f} at the start, {facts['load_end']:.1f} at the end, on "
                   f"{facts['cores']} cores; {facts['wall']:.0f} s in all\n")


def main(argv: Sequence[str] | None = None) -> int:
    p = C.parser(__doc__.splitlines()[0])
    p.add_argument("--against", default=AGAINST, metavar="REV", help=f"git revision B (default {AGAINST})")
    p.add_argument("--flights", type=int, default=4, help="cases a sweep (its first N; default 4)")
    p.add_argument("--specs", default=",".join(SPECS), help="de-orbit sweeps, by name in sweeps/ (comma-separated)")
    args = p.parse_args(argv)
    specs = [s.strip() for s in args.specs.split(",") if s.strip()]
    flights = args.flights
    if args.quick:
        specs, flights = specs[:1], 1
    table, facts = rows(args.against, specs, flights, log=sys.stderr)
    print(format_table(table, facts))
    C.write_json(args.json, {"facts": facts, "rows": table})
    return 0


if __name__ == "__main__":
    sys.exit(main())
