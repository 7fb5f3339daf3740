"""``lander sweep SPEC``: many seeded, dispersed flights core-only (no ROS), one summary.

Examples::

    lander sweep sweeps/hover-robustness.yaml                 # all local cores, progress bar
    lander sweep sweeps/hover-robustness.yaml --flights 50 --workers 2 --out /tmp/sw
    lander sweep sweeps/hover-robustness.yaml --dask          # local Dask cluster, 2 workers
    lander sweep sweeps/hover-robustness.yaml --dask tcp://scheduler:8786
    lander sweep sweeps/hover-robustness.yaml --replay 17     # re-fly flight 17 alone, print metrics
    lander sweep sweeps/hover-robustness.yaml --replay 17 --record out/f17   # ... through the ROS nodes, into a bag
    lander sweep sweeps/hover-robustness.yaml --through-ros 5 # + first 5 through the nodes, check agreement
    lander sweep sweeps/compare-combined-lqr.yaml             # two controllers on the same cases

Writes ``flights.csv``, ``flights.json`` (and ``flights.parquet`` with pyarrow), ``summary.json``,
``summary.txt`` and PNG plots into ``--out`` (default ``out/sweep/<spec name>`` in the current
folder: ``out/`` is git-ignored, so a sweep run in the checkout adds nothing to it).
Heavy imports happen in :func:`run` so ``lander --help`` stays fast.
"""
from __future__ import annotations

import argparse
from typing import Any

#: Where a sweep writes without ``--out`` (relative to the working folder; ``/out/`` is in .gitignore).
DEFAULT_OUT = "out/sweep"

EXIT_USAGE = 2
EXIT_NOT_AVAILABLE = 3
EXIT_DISAGREE = 4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", metavar="SPEC", help="sweep specification, YAML file (see docs/sweeps.md)")
    parser.add_argument("--flights", type=int, default=None, metavar="N", help="override the spec's number of flights")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="worker processes (default: every core; with --dask: 2)")
    parser.add_argument(
        "--dask", nargs="?", const="local", default=None, metavar="ADDRESS",
        help="run on Dask distributed: a LocalCluster, or the scheduler at ADDRESS (tcp://host:8786)",
    )
    parser.add_argument("--path", choices=("auto", "batched", "per-flight"), default="auto",
                        help="batched (compiled core) or per-flight; default: batched when every law can fly on it")
    parser.add_argument("--out", default=None, metavar="DIR", help=f"output folder (default {DEFAULT_OUT}/<spec name>, in the current folder)")
    parser.add_argument("--json", action="store_true", help="print the summary (or the replayed metrics) as JSON")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress bar on stderr (default: only on a terminal)")
    parser.add_argument("--replay", type=int, default=None, metavar="INDEX",
                        help="re-fly flight INDEX alone (bit-identical to the sweep's) and print its metrics")
    parser.add_argument("--record", default=None, metavar="BAG",
                        help="with --replay: fly it through the ROS nodes (the `lander fly` path) into a bag")
    parser.add_argument("--through-ros", type=int, default=None, metavar="N",
                        help="also fly the first N flights through the ROS nodes (lockstep) and check that "
                             "their metrics agree with core-only (run with ./dev sweep ...)")
    parser.add_argument("--ros-speed", type=float, default=0.0, metavar="X",
                        help="with --through-ros: real-time factor of those flights (default 0: as fast as possible)")


def _fail(msg: str, code: int = EXIT_USAGE) -> int:
    import sys

    print(f"lander sweep: {msg}", file=sys.stderr)
    return code


def _fmt_row(r: dict[str, Any]) -> str:
    return "  ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items() if v != "")


def run(args: argparse.Namespace) -> int:
    import dataclasses
    import json
    from pathlib import Path

    from lander_tools.sweep import flight as fl
    from lander_tools.sweep import output, summary
    from lander_tools.sweep.runner import run_dask, run_local
    from lander_tools.sweep.spec import load_spec

    try:
        spec = load_spec(args.spec)
        if args.flights is not None:
            if args.flights < 1:
                return _fail(f"--flights: must be >= 1, got {args.flights}")
            spec = dataclasses.replace(spec, flights=args.flights)
        if args.workers is not None and args.workers < 1:
            return _fail(f"--workers: must be >= 1, got {args.workers}")
        if args.record is not None and args.replay is None:
            return _fail("--record needs --replay INDEX (it records one flight)")
        if args.through_ros is not None and args.through_ros < 1:
            return _fail(f"--through-ros: must be >= 1 flight, got {args.through_ros}")
        if args.through_ros is not None and args.through_ros > spec.flights:
            return _fail(f"--through-ros: {args.through_ros} is more than the sweep's {spec.flights} flights")
        if not args.ros_speed >= 0.0:
            return _fail(f"--ros-speed: must be >= 0 (0 = as fast as possible), got {args.ros_speed}")
        if args.replay is not None and args.replay < 0:
            return _fail(f"--replay: a flight index must be >= 0, got {args.replay}")
        # Fail once, here, on what would fail every flight (scene, controller, control rate).
        fl.preflight(spec)
    except ValueError as exc:  # SweepSpecError, SceneError, ControllerError, FlightSetupError
        return _fail(str(exc))

    if args.replay is not None:
        if args.record is not None:
            return _replay_recorded(spec, args)
        replayed = [fl.fly_case(spec, ci, args.replay).row for ci in range(len(spec.controllers))]
        print(json.dumps(output.jsonable(replayed), indent=1) if args.json else "\n".join(_fmt_row(r) for r in replayed))
        return 0

    if args.path == "batched":
        from lander_tools.sweep.batched import unsupported_reason

        why = unsupported_reason(spec)
        if why is not None:
            return _fail(f"--path batched: the batched core cannot fly this sweep: {why}")
    if args.dask is not None:
        address = None if args.dask == "local" else args.dask
        result = run_dask(spec, address=address, workers=args.workers, progress=args.progress, path=args.path)
    else:
        result = run_local(spec, workers=args.workers, progress=args.progress, path=args.path)

    rows = result.rows
    sums = summary.summarise(rows, spec.metrics, acceptance=spec.acceptance)
    labels = [c.label for c in spec.controllers]
    comps = [summary.compare(rows, labels[0], b, spec.metrics) for b in labels[1:]]
    text = summary.format_summary(sums, comps)
    speed = (
        f"{len(rows)} flights in {result.wall_time:.1f} s on {result.workers} {result.engine} worker(s): "
        f"{result.flights_per_second:.2f} flights/s (core-only, no ROS; {result.path_note} path)"
    )
    blob: dict[str, Any] = {
        "spec": spec.source, "name": spec.name, "seed": spec.seed, "flights": spec.flights,
        "engine": result.engine, "workers": result.workers, "wall_time_s": result.wall_time,
        "flights_per_second": result.flights_per_second, "path": result.path, "path_reason": result.path_reason,
        **summary.to_jsonable(sums, comps),
    }
    out = Path(args.out) if args.out else Path(DEFAULT_OUT) / spec.name
    check = None
    if args.through_ros:
        try:
            from lander_tools.sweep.ros_path import through_ros

            # The nodes fly the per-flight path's equations bit for bit; the batched core agrees with it
            # to round-off only, so compare with per-flight rows (through_ros flies them) in that case.
            core = rows if result.path != "batched" else None
            check = through_ros(spec, args.through_ros, out / "ros", core_rows=core, speed=args.ros_speed)
        except ImportError as exc:
            return _fail(f"--through-ros needs the ROS environment (run it with ./dev sweep ...): {exc}", EXIT_NOT_AVAILABLE)
        blob["through_ros"] = {**check.as_dict(), "core_flights_per_second": result.flights_per_second,
                               "summary": check.summary()}
    written = output.write_all(out, rows, blob, text + "\n" + speed)
    if not args.no_plots:
        from lander_tools.sweep.plots import all_plots

        written += all_plots(spec, rows, out / "plots")

    if args.json:
        print(json.dumps(output.jsonable(blob), indent=1, allow_nan=False))
    else:
        print(text)
        print(speed)
        print("wrote: " + ", ".join(str(p) for p in written))
        if check is not None:
            print(check.summary())
    errors = [r for r in rows if r["outcome"] == "error"]
    if errors:
        print(f"lander sweep: warning: {len(errors)} flight(s) raised; first (#{errors[0]['index']}): {errors[0]['error']}")
    if check is not None and not check.agree:
        return EXIT_DISAGREE
    return 0


def _replay_recorded(spec: Any, args: argparse.Namespace) -> int:
    """Fly one case through the ROS nodes (the ``lander fly`` path, lockstep, max speed) into a bag."""
    import tempfile
    from pathlib import Path

    try:
        from lander_tools.fly.phases import fly  # the `lander fly` path: rclpy
    except ImportError as exc:
        return _fail(f"--record needs the ROS environment (run it with ./dev sweep ...): {exc}", EXIT_NOT_AVAILABLE)
    from lander_tools.fly.summary import summary
    from lander_tools.sweep.ros_path import plan_for_case

    code = 0
    with tempfile.TemporaryDirectory(prefix="lander-sweep-") as tmp:
        for ci, choice in enumerate(spec.controllers):
            bag = Path(args.record) if len(spec.controllers) == 1 else Path(f"{args.record}-{choice.label}")
            plan = plan_for_case(spec, ci, args.replay, Path(tmp), bag)  # NotRepresentable is a ValueError
            result = fly(plan)
            print(summary(result))
            code = max(code, result.exit_code)
    return code
