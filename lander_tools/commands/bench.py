"""`lander bench NAME`: run one of the benchmarks in bench/ (integrators, extremes, models, speed, closed_loop, ...).

Each benchmark is ``bench/NAME.py`` with ``main(argv) -> int``; this command finds the bench
directory (the source checkout next to this package, or ``$LANDER_BENCH_DIR``), loads the file and
passes the options on. Heavy imports (numpy, scipy, numba) happen only inside :func:`run`.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import sys
from pathlib import Path

BENCHMARKS = {
    "integrators": "work-precision of every integrator and scipy's solve_ivp; long-run drift",
    "extremes": "stability map over step and spin rate, gimbal lock, odd inertia, bang-bang",
    "models": "steps per second of each scene and with models added one by one",
    "speed": "raw Verlet step speed: compiled kernel vs numpy path vs naive",
    "node_rtf": "real-time factor of the sim node at 1 kHz physics, 50 Hz publishing (ROS)",
    "full_stack": "sim + autopilot + recorder flying scenario 7: RTF, latency, CPU, lost messages (ROS)",
    "closed_loop": "closed loop in Python vs compiled, and the per-flight vs batched sweep paths",
    "ceiling": "compiled kernel vs a fused loop of the same physics written only to be fast (what the machine can do)",
    "guidance_reference": "the fuel-optimal reference from de-orbit handover states: wall time, solves, fuel vs a git revision",
    "guard": "regression guard: the compiled paths of the working tree vs --against REV, side by side (ratios)",
}


def _bench_dir() -> Path:
    env = os.environ.get("LANDER_BENCH_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "bench"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", metavar="NAME", help="benchmark: " + "; ".join(f"{k} ({v})" for k, v in BENCHMARKS.items()))
    parser.add_argument("--json", metavar="FILE", help="also write the figures machine-readable to FILE")
    parser.add_argument("--out", metavar="DIR", help="directory for the PNG plots")
    parser.add_argument("--quick", action="store_true", help="small version (< 60 s each)")
    parser.add_argument("--against", metavar="REV", help="guard and guidance_reference only: the git revision to time the working tree against")
    parser.add_argument("--runs", type=int, metavar="N", help="guard only: runs per tree (default 5)")
    parser.add_argument("--figures", metavar="A,B", help="guard only: which figures (default all)")


def run(args: argparse.Namespace) -> int:
    if args.name not in BENCHMARKS:
        raise ValueError(f"unknown benchmark {args.name!r}; choose one of: {', '.join(BENCHMARKS)}")
    path = _bench_dir() / f"{args.name}.py"
    if not path.is_file():
        raise ValueError(f"benchmark file {path} not found (set LANDER_BENCH_DIR to the project's bench/ directory)")
    if str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(f"lander_bench_{args.name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses in the benchmark look their module up here
    spec.loader.exec_module(module)
    argv: list[str] = []
    if args.json:
        argv += ["--json", args.json]
    if args.out:
        argv += ["--out", args.out]
    if args.quick:
        argv.append("--quick")
    guard_only = {"--against": getattr(args, "against", None), "--runs": getattr(args, "runs", None),
                  "--figures": getattr(args, "figures", None)}
    given = {k: v for k, v in guard_only.items() if v is not None}
    allowed = {"guard": set(guard_only), "guidance_reference": {"--against"}}.get(args.name, set())
    if set(given) - allowed:
        raise ValueError(f"{', '.join(sorted(set(given) - allowed))}: options of the guard benchmark only")
    for k, v in given.items():
        argv += [k, str(v)]
    return int(module.main(argv))
