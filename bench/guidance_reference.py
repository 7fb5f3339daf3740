"""The fuel-optimal reference in real time: wall time, convex solves and fuel, two trees side by side.

The MPC's powered descent starts from the minimum-fuel descent of
:func:`lander_autopilot.guidance.fuel_optimal.solve` (free final time, drag by successive
convexification), solved inside one 0.1 s control period at the handover; the de-orbit sweeps
use the same function as their fuel yardstick. This bench takes the handover states of

* the bench's four: the flights of bench/deorbit_fuel.py (scene ``deorbit`` and ``deorbit-200km``,
  laws ``deorbit`` and ``deorbit-mpc``), the state at the control instant the powered descent
  begins, the problem as that bench poses it (:func:`deorbit_fuel.optimum`'s);
* sweep cases of sweeps/deorbit.yaml and sweeps/deorbit-200km.yaml, the scheduled law flown as the
  sweep flies it (:func:`lander_tools.sweep.flight.flown_periods`) to the same instant, the problem
  as the sweep's yardstick poses it (:func:`lander_tools.sweep.flight.yardstick_problem`),

and solves each with the MPC's reference settings (the de-orbit law's 20 nodes, ``--steps`` for
another number; final time to 1e-3 s: ``descent_mpc.REFERENCE_TIME_TOLERANCE``) in the working tree (A) and in a git revision (B, default
``9cab8fa``), each tree exported and run in a fresh interpreter of its own (bench/guard.py's
export), one after the other on the same states. One table: wall time median / p99 / max of a
reference, convex solves per reference, the fuel of each tree and the largest relative fuel
difference. The handover states are flown once and kept in ``out/guidance_reference/``.

    ./dev bench guidance_reference                # 4 + 2 x 26 states, both trees (B ~10-15 min; the states,
                                                  # flown once, ~6 min on 2 workers)
    ./dev bench guidance_reference --quick        # a smoke run: the first 8 of those states

The CPU time beside the wall time is the process's (Clarabel runs one thread): on a shared
machine the wall time is that and the waiting for a core.
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
from dataclasses import dataclass
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import _common as C
import numpy as np

#: The revision the working tree is timed against (the reference before it ran in real time).
AGAINST = "9cab8fa"
SWEEPS = ("sweeps/deorbit.yaml", "sweeps/deorbit-200km.yaml")
#: [m] the demand altitude of bench/deorbit_fuel.py's flights
BENCH_DEMAND = 500.0
#: the MPC's reference settings: the de-orbit law's ``reference_steps`` (20 nodes,
#: lander_autopilot/controllers/deorbit/params.py: what flies; ``--steps 60`` for the guidance's
#: own default, descent_mpc.MpcSettings) and REFERENCE_TIME_TOLERANCE
STEPS, T_TOL = 20, 1e-3
STATE_DIR = C.ROOT / "out" / "guidance_reference"


# --- handover states (flown once, kept as plain numbers) ------------------------------------------


def problem_record(problem: Any) -> dict[str, Any]:
    """A :class:`DescentProblem` as plain numbers (JSON): any tree rebuilds it with :func:`problem_of`."""
    lim, drag = problem.limits, problem.drag
    return {
        "position_L": [float(x) for x in problem.position_L], "velocity_L": [float(x) for x in problem.velocity_L],
        "mass": float(problem.mass), "gravity": float(problem.gravity), "target_L": [float(x) for x in problem.target_L],
        "free_horizontal": bool(problem.free_horizontal), "end_band": float(problem.end_band),
        "end_speed": float(problem.end_speed),
        "limits": {k: float(getattr(lim, k)) for k in ("rho_max", "alpha", "dry_mass", "rho_min", "max_tilt", "glide_slope")},
        "drag": None if drag is None else {"k": float(drag.k), "surface_density": float(drag.surface_density),
                                           "scale_height": float(drag.scale_height),
                                           "wind_L": [float(x) for x in drag.wind_L]},
    }


def problem_of(rec: dict[str, Any]) -> Any:
    from lander_autopilot.guidance.fuel_optimal import DescentLimits, DescentProblem, DragModel

    d = rec["drag"]
    drag = None if d is None else DragModel(d["k"], d["surface_density"], d["scale_height"], tuple(d["wind_L"]))
    return DescentProblem(position_L=np.array(rec["position_L"]), velocity_L=np.array(rec["velocity_L"]),
                          mass=rec["mass"], gravity=rec["gravity"], limits=DescentLimits(**rec["limits"]),
                          target_L=np.array(rec["target_L"]), free_horizontal=rec["free_horizontal"], drag=drag,
                          end_band=rec["end_band"], end_speed=rec["end_speed"])


def _bench_state(args: tuple[str, str]) -> dict[str, Any]:
    """The handover of bench/deorbit_fuel.py's flight of ``(scene, law)``: flown to the control
    instant the powered descent begins (that bench's loop), posed as that bench's ``optimum``."""
    from lander_autopilot.controllers import Demand
    from lander_autopilot.controllers.deorbit_mpc import handover_problem
    from lander_autopilot.controllers.registry import make_controller
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    scene_name, law = args
    sc = load_scene(scene_name)
    sim = Simulation(sc)
    ctrl = make_controller(law, sc.vehicle)
    demand = Demand(altitude=BENCH_DEMAND)
    while sim.t < 10_000.0:
        s = sim.state()
        out = ctrl.update(sim.t, s, demand)
        if ctrl.phase.value == "powered-descent":
            problem, _ = handover_problem(sc.vehicle, s.r_W, s.v_W, float(s.fuel), BENCH_DEMAND)
            return {"source": f"bench {scene_name}/{law}", **problem_record(problem)}
        for r in out.requests:
            if r.kind == "deploy_parachute":
                sim.deploy_parachute()
        sim.set_throttles(out.throttles)
        sim.step()
    raise RuntimeError(f"{scene_name}/{law}: no powered descent")


def _sweep_state(args: tuple[str, int]) -> dict[str, Any] | None:
    """The handover of sweep case ``index`` flown by the spec's scheduled law (the sweep's loop),
    posed as the sweep's yardstick poses it; None for a case that never begins a powered descent."""
    from lander_tools.sweep.dispersion import draw_case
    from lander_tools.sweep.flight import (
        chute_is_open,
        demand_schedule,
        flown_periods,
        nominal_scene,
        yardstick_problem,
    )
    from lander_tools.sweep.spec import load_spec

    spec_path, index = args
    spec = load_spec(str(C.ROOT / spec_path))
    ci = [ch.label for ch in spec.controllers].index("scheduled")
    scene0 = nominal_scene(spec)
    _before, h_after, _t_change = demand_schedule(spec, scene0, draw_case(spec, index, scene0.vehicle.n_thrusters))
    for _t, st, ctrl, sim in flown_periods(spec, ci, index):
        if ctrl.phase.value == "powered-descent":
            # st is the state the law was given at the instant it began the powered descent
            handover = (st.r_W.copy(), st.v_W.copy(), float(st.fuel), chute_is_open(sim))
            problem = yardstick_problem(sim, handover, h_after)
            return {"source": f"{spec.name} case {index}", **problem_record(problem)}
    return None


def handover_states(cases: int, workers: int = 2) -> list[dict[str, Any]]:
    """The bench's four and ``cases`` cases of each de-orbit sweep, flown once and kept on disk."""
    STATE_DIR.mkdir(parents=True, exist_ok=True)
    path = STATE_DIR / f"states-{cases}.json"
    if path.exists():
        return list(json.loads(path.read_text()))
    tasks_bench = [(s, law) for s in ("deorbit", "deorbit-200km") for law in ("deorbit", "deorbit-mpc")]
    tasks_sweep = [(spec, i) for spec in SWEEPS for i in range(cases)]
    t0 = time.perf_counter()
    with Pool(workers) as pool:
        bench = pool.map(_bench_state, tasks_bench, chunksize=1)
        sweep = pool.map(_sweep_state, tasks_sweep, chunksize=1)
    states = bench + [s for s in sweep if s is not None]
    path.write_text(json.dumps(states, indent=1))
    print(f"flew {len(tasks_bench) + len(tasks_sweep)} flights to their handover in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    return states


# --- the reference timed in one tree (runs inside that tree's interpreter) -----------------------


def time_references(states: Sequence[dict[str, Any]], steps: int = STEPS, t_tol: float = T_TOL) -> list[dict[str, Any]]:
    """Solve each state's reference in this interpreter's tree: wall time [s], convex solves (every
    cvxpy ``Problem.solve`` call, or the result's ``solve_count`` where the tree solves without
    cvxpy), fuel [kg] and final time [s]."""
    import cvxpy as cp

    from lander_autopilot.guidance import fuel_optimal

    calls = [0]
    plain = cp.Problem.solve

    def counted(self: Any, *a: Any, **k: Any) -> Any:
        calls[0] += 1
        return plain(self, *a, **k)

    cp.Problem.solve = counted  # type: ignore[method-assign]  # counts the tree's cvxpy solves
    # one solve beforehand: imports and first-call set-up, which a flight pays at start-up
    fuel_optimal.solve(problem_of(states[0]), steps=steps, t_tol=t_tol)
    out = []
    for rec in states:
        problem = problem_of(rec)
        calls[0] = 0
        c0, t0 = time.process_time(), time.perf_counter()
        try:
            sol = fuel_optimal.solve(problem, steps=steps, t_tol=t_tol)
            fuel, tf, count = sol.fuel, sol.final_time, sol.solve_count
        except fuel_optimal.GuidanceError:
            fuel = tf = math.nan
            count = 0
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        out.append({"source": rec["source"], "wall": wall, "cpu": cpu, "solves": calls[0] or count, "fuel": fuel,
                    "final_time": tf})
    cp.Problem.solve = plain  # type: ignore[method-assign]
    return out


_RUNNER = """
import json, sys
root, bench, states, out, steps = sys.argv[1:]
sys.path.insert(0, root)
import importlib
from pathlib import Path
for name in ("lander_yaml", "lander_sim", "lander_autopilot", "lander_tools"):  # the tree's, before the bench's
    if (Path(root) / name / "__init__.py").is_file():
        importlib.import_module(name)
sys.path.insert(1, bench)
import guidance_reference as g
rows = g.time_references(json.loads(Path(states).read_text()), steps=int(steps))
import lander_autopilot
rows = {"rows": rows, "package": lander_autopilot.__file__}
Path(out).write_text(json.dumps(rows))
"""


def _run_tree(root: Path, states: Path, out: Path, steps: int = STEPS) -> list[dict[str, Any]]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(root), *filter(None, [env.get("PYTHONPATH")])])
    proc = subprocess.run([sys.executable, "-c", _RUNNER, str(root), str(Path(__file__).resolve().parent), str(states),
                           str(out), str(steps)], env=env, capture_output=True, text=True, cwd=str(root))
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"references in {root} failed: {tail}")
    res = json.loads(out.read_text())
    if not Path(res["package"]).resolve().is_relative_to(root.resolve()):
        raise RuntimeError(f"tree {root} imported lander_autopilot from {res['package']}")
    return list(res["rows"])


# --- the table ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """One tree on one set of handover states (SI units)."""

    tree: str
    states: str
    n: int
    wall_median: float  # [s]
    wall_p99: float
    wall_max: float
    cpu_median: float  # [s] CPU time of the process (the solvers are single-threaded): what the
    cpu_p99: float  #      reference costs with the machine to itself
    solves_median: float
    fuel_mean: float  # [kg]
    fuel_diff_max: float  # largest |fuel_A - fuel_B| / fuel_B over the states (0 for B)


def summarise(a: Sequence[dict[str, Any]], b: Sequence[dict[str, Any]], name_a: str, name_b: str) -> list[Row]:
    """Rows for the bench's four, the sweep states and all of them, tree A then tree B."""
    rows = []
    groups = {"the bench's four": lambda s: s.startswith("bench"), "sweep cases": lambda s: not s.startswith("bench"),
              "all": lambda s: True}
    for label, keep in groups.items():
        idx = [i for i, r in enumerate(a) if keep(r["source"])]
        if not idx:
            continue
        for name, side in ((name_a, a), (name_b, b)):
            wall = np.array([side[i]["wall"] for i in idx])
            fuel = np.array([side[i]["fuel"] for i in idx])
            ref = np.array([b[i]["fuel"] for i in idx])
            diff = np.abs(fuel - ref) / ref
            cpu = np.array([side[i]["cpu"] for i in idx])
            rows.append(Row(name, label, len(idx), float(np.median(wall)), float(np.percentile(wall, 99)),
                            float(wall.max()), float(np.median(cpu)), float(np.percentile(cpu, 99)),
                            float(np.median([side[i]["solves"] for i in idx])),
                            float(np.nanmean(fuel)), float(np.nanmax(diff)) if np.isfinite(diff).any() else math.nan))
    return rows


def format_table(rows: Sequence[Row]) -> str:
    body = [[r.tree, r.states, str(r.n), f"{1e3 * r.wall_median:.1f}", f"{1e3 * r.wall_p99:.1f}", f"{1e3 * r.wall_max:.1f}",
             f"{1e3 * r.cpu_median:.1f}", f"{1e3 * r.cpu_p99:.1f}", f"{r.solves_median:.0f}", f"{r.fuel_mean:.4f}",
             f"{100 * r.fuel_diff_max:.4f}"] for r in rows]
    header = ["tree", "handover states", "n", "wall median [ms]", "p99", "max", "CPU median [ms]", "p99",
              "convex solves (median)", "mean fuel [kg]", "max |dfuel| / fuel_B [%]"]
    w = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(header)]
    line = "  ".join(h.ljust(w[i]) for i, h in enumerate(header))
    out = [line, "-" * len(line)] + ["  ".join(c.ljust(w[i]) if i < 2 else c.rjust(w[i]) for i, c in enumerate(r)) for r in body]
    return "\n".join(out) + "\n"


def compare(against: str = AGAINST, cases: int = 26, limit: int | None = None,
            steps: int = STEPS) -> tuple[list[Row], dict[str, Any]]:
    """The table's rows, the working tree (A) against ``against`` (B), both exported and run in
    fresh interpreters on the same states (A first, then B); and the per-state figures."""
    from guard import export_revision, export_working_tree

    states = handover_states(cases)[:limit]
    with tempfile.TemporaryDirectory(prefix="lander-reference-") as tmp:
        tree_a, tree_b = Path(tmp) / "working", Path(tmp) / "tree"
        tree_a.mkdir()
        tree_b.mkdir()
        export_working_tree(C.ROOT, tree_a)
        full = export_revision(against, C.ROOT, tree_b)
        path = Path(tmp) / "states.json"
        path.write_text(json.dumps(states))
        load0 = os.getloadavg()[0]
        a = _run_tree(tree_a, path, Path(tmp) / "a.json", steps)
        b = _run_tree(tree_b, path, Path(tmp) / "b.json", steps)
        load1 = os.getloadavg()[0]
    name_a, name_b = "A working tree", f"B {against} ({full[:10]})"
    return summarise(a, b, name_a, name_b), {"a": a, "b": b, "commit": full, "load": (load0, load1)}


def main(argv: Sequence[str] | None = None) -> int:
    p = C.parser(__doc__.splitlines()[0])
    p.add_argument("--against", metavar="REV", default=AGAINST, help=f"git revision to time against (B; default {AGAINST})")
    p.add_argument("--cases", type=int, default=26, help="cases of each de-orbit sweep (default 26)")
    p.add_argument("--steps", type=int, default=STEPS,
                   help=f"nodes of the reference (default {STEPS}, the de-orbit MPC's; 60 is the guidance's default)")
    args = p.parse_args(argv)
    rows, data = compare(args.against, args.cases, 8 if args.quick else None, args.steps)
    print(f"The fuel-optimal reference from de-orbit handover states ({args.steps} nodes, final time to {T_TOL:g} relative), "
          f"A = working tree, B = {args.against}; load average {data['load'][0]:.1f} / {data['load'][1]:.1f} "
          f"on {os.cpu_count()} cores")
    print(format_table(rows))
    worst = max(data["a"], key=lambda r: abs(r["fuel"] - data["b"][data["a"].index(r)]["fuel"]))
    print(f"largest fuel difference: {worst['source']}")
    C.write_json(args.json, {"rows": [r.__dict__ for r in rows], **data})
    return 0


if __name__ == "__main__":
    sys.exit(main())
