"""``lander analyse BAG...``: metrics and plots from recorded flights (bags).

One bag: a metrics table (or ``--json``) and, with ``--out``, the standard plots.
Two or more: the same side by side, metric differences against the first bag and
overlaid plots. A damaged bag is read as far as it goes, with a warning; an
unreadable one is a one-line error (exit 2), never a traceback.

``--reference``: for each de-orbit flight, the powered descent against the fuel-optimal reference
from its handover state (:mod:`lander_tools.reference_overlay`): printed after the table (or as
``"reference"`` in the JSON, one entry per bag) and, with ``--out``, plotted to
``<prefix>-reference.png`` (``<prefix>-reference-<n>.png`` for the n-th of several bags). A bag
without a powered descent gets one line on stderr and ``null``, exit 0, as a metric that does not
apply; a reference that cannot be built (no scene in the bag's metadata and no ``--scene``, no
demand, no feasible descent) is a one-line error, exit 2.
A bag that holds the estimate (a flight flown with ``lander fly --estimate``) gets the estimate's
figures after the table (:mod:`lander_tools.estimate_analysis`): per state component the error
against the truth with percentiles and the fraction inside the filter's 3 sigma, the NEES of
position, velocity, attitude and pose against their chi-square 95 % intervals, and the NIS of each
sensor's updates from the filter re-run over the bag's sensor messages, once the re-run reproduces
the recorded estimate bit for bit (:mod:`lander_tools.estimate_nis`; else NIS n/a with the reason);
as ``"estimate"`` in the JSON (one entry per bag, ``"applies": false`` with the reason where the bag
has no estimate); with ``--out``, ``<prefix>-estimate.png`` (error and +-3 sigma per component),
``<prefix>-nees.png`` and, with NIS, ``<prefix>-nis.png`` (``-<n>`` before ``.png`` for the n-th of
several bags). Bags without an estimate print nothing of it in the table.
Heavy imports (numpy, matplotlib, rosbags, cvxpy) happen in :func:`run`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", metavar="BAG", nargs="+", type=Path,
                        help="rosbag2 folder(s) (or .mcap files) recorded by 'lander fly --record'")
    parser.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    parser.add_argument("--out", metavar="DIR", type=Path, help="write plots (PNG) to this folder")
    parser.add_argument("--prefix", default="flight", help="file name prefix of the plots (default: flight)")
    parser.add_argument("--band", type=float, default=0.5, metavar="M",
                        help="smallest settling band, m (default 0.5; else 2%% of the step)")
    parser.add_argument("--reference", action="store_true",
                        help="de-orbit flights (controllers deorbit, deorbit-mpc): the powered descent's fuel against "
                        "the fuel-optimal descent from its handover state to the hover, and with --out its plot "
                        "(PREFIX-reference.png); solves a convex programme, ~5-15 s per bag")
    parser.add_argument("--scene", metavar="NAME",
                        help="with --reference: the flight's scene (name or YAML path) for a bag whose metadata "
                        "names none, e.g. an MCAP cut short (no metadata.yaml)")


def run(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from lander_tools.analysis import Flight, metrics, table, to_json
    from lander_tools.bagio import BagError, BagWarning, read_bag

    if args.scene is not None and not args.reference:
        print("lander analyse: --scene is used only with --reference", file=sys.stderr)
        return 2
    problem = _out_problem(args.out, args.prefix)
    if problem:
        print(f"lander analyse: {problem}", file=sys.stderr)
        return 2
    flights: list[Flight] = []
    estimates: list[tuple[Any, str]] = []  # per bag: (EstimateReport or None, why not)
    for path in args.bags:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", BagWarning)
            try:
                bag = read_bag(path)
                flights.append(Flight.from_bag(bag, name=_name(path, [f.name for f in flights])))
                _print_span(path, bag)
                estimates.append(_estimate(path, bag, flights[-1]))
            except BagError as exc:
                print(f"lander analyse: {exc}", file=sys.stderr)
                return 2
        for w in caught:
            print(f"lander analyse: warning: {w.message}", file=sys.stderr)
    all_metrics = [metrics(f, band_min=args.band) for f in flights]
    rc, overlays = (_references(flights, args.bags, args.scene) if args.reference else (0, []))
    extra: dict[str, Any] = {"reference": [None if o is None else o.summary() for o in overlays]} if args.reference else {}
    extra["estimate"] = [rep.summary() if rep is not None else {"applies": False, "name": f.name, "why": why}
                         for f, (rep, why) in zip(flights, estimates)]
    print(to_json(all_metrics, extra) if args.json else table(all_metrics))
    if not args.json:
        for o in overlays:
            if o is not None:
                print()
                print("\n".join(o.lines()))
        if any(rep is not None for rep, _ in estimates):
            for f, (rep, why) in zip(flights, estimates):
                print()
                print("\n".join(rep.lines()) if rep is not None else f"estimate of {f.name}: n/a: {why}")
    if args.out is not None:
        try:
            _write_figures(flights, overlays, args.out, args.prefix)
            _write_estimate_figures([rep for rep, _ in estimates], args.out, args.prefix)
        except OSError as exc:  # the checks above cannot see everything (a read-only mount, a full disk)
            print(f"lander analyse: --out {args.out}: cannot write the plots: {exc.strerror or exc}", file=sys.stderr)
            return 2
    return rc


def _write_figures(flights: list[Any], overlays: list[Any], out: Path, prefix: str) -> None:
    import sys

    from lander_tools.analysis_plots import write_plots
    from lander_tools.reference_overlay import write_figure

    out.mkdir(parents=True, exist_ok=True)
    for p in write_plots(flights, out, prefix):
        print(f"wrote {p}", file=sys.stderr)
    for k, (f, o) in enumerate(zip(flights, overlays)):
        if o is not None:
            name = f"{prefix}-reference.png" if len(flights) == 1 else f"{prefix}-reference-{k + 1}.png"
            print(f"wrote {write_figure(f, o, out / name)}", file=sys.stderr)


def _estimate(path: Path, bag: Any, flight: Any) -> tuple[Any, str]:
    """The flight's :class:`~lander_tools.estimate_analysis.EstimateReport` and ``""``, or ``None``
    and why not; an estimate topic that cannot be read is one line on stderr, and the table goes on."""
    import sys

    from lander_tools import estimate_analysis as ea

    try:
        return ea.from_bag(bag, flight)
    except (KeyError, ValueError) as exc:
        why = f"{ea.ODOMETRY_TOPIC} cannot be read as nav_msgs/Odometry ({type(exc).__name__}: {exc})"
        print(f"lander analyse: warning: {path}: {why}", file=sys.stderr)
        return None, why


def _write_estimate_figures(reports: list[Any], out: Path, prefix: str) -> None:
    import sys

    from lander_tools.estimate_analysis import write_figures

    for k, rep in enumerate(reports):
        if rep is not None:
            out.mkdir(parents=True, exist_ok=True)
            for p in write_figures(rep, out, prefix, "" if len(reports) == 1 else f"-{k + 1}"):
                print(f"wrote {p}", file=sys.stderr)


def _references(flights: list[Any], paths: list[Path], scene: str | None) -> tuple[int, list[Any]]:
    """Each flight's :class:`~lander_tools.reference_overlay.Overlay` (None where it does not
    apply or cannot be built: one line on stderr each); exit 2 if any could not be built."""
    import sys

    from lander_tools import reference_overlay as ro

    rc = 0
    out: list[Any] = []
    for f, path in zip(flights, paths):
        try:
            setup = ro.prepare(f, scene)  # quick: what does not apply or cannot be built is told at once
            print(f"lander analyse: {path}: solving the fuel-optimal reference (~5-15 s)", file=sys.stderr)
            out.append(ro.solve_reference(setup))
        except ro.NotApplicable as exc:
            print(f"lander analyse: {path}: no fuel-optimal reference: {exc}", file=sys.stderr)
            out.append(None)
        except ro.OverlayError as exc:
            print(f"lander analyse: {path}: {exc}", file=sys.stderr)
            out.append(None)
            rc = 2
    return rc, out


def _out_problem(out: Path | None, prefix: str) -> str | None:
    """What is wrong with the plots' folder ``out`` and file ``prefix``, checked before any bag is
    read (the folder is made only when the plots are written); ``None`` if they can be used."""
    import os

    if not prefix or prefix in (".", "..") or "/" in prefix or os.sep in prefix:
        return f"--prefix {prefix!r}: give a plain file-name start (no folder: that is --out)"
    if out is None:
        return None
    if out.exists() and not out.is_dir():
        return f"--out {out}: not a folder (a file of that name exists); give a folder for the plots"
    base = out
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():
        return f"--out {out}: {base} is a file, so no folder can be made under it; give a folder for the plots"
    if not os.access(base, os.W_OK | os.X_OK):
        return f"--out {out}: cannot write in {base} (permission denied); give a folder you can write to"
    return None


def _name(path: Path, taken: list[str]) -> str:
    name = path.name if path.name else str(path)
    return name if name not in taken else f"{name}#{len(taken) + 1}"


def _print_span(path: Path, bag: Any) -> None:
    """Each bag's span on stderr (stdout stays the table or JSON); a bag that is not one whole
    flight is flagged (lander_tools.bagspan)."""
    import sys

    from lander_tools.bagspan import bag_span

    if "/lander/state" not in bag.topics:
        return
    s = bag.series("/lander/state")
    span = bag_span(s["t"], s["sequence"])
    flag = "warning: " if span.problems() else ""
    print(f"lander analyse: {flag}{path}: states {span.describe()}", file=sys.stderr)
    # A lockstep flight whose sim advanced without some answers is not the deterministic one: its
    # FLIGHT_ENDED says how many (lander_ros.flight_span); bags recorded before the count read 0.
    from lander_ros.flight_span import FlightEnd, lockstep_warning
    from lander_tools.analysis import EV_FLIGHT_ENDED

    for m in bag.messages("/lander/events") if "/lander/events" in bag.topics else []:
        if int(m.kind) != EV_FLIGHT_ENDED:
            continue
        try:
            warning = lockstep_warning(FlightEnd.from_values(list(m.values)).lockstep_timeouts)
        except ValueError as exc:
            print(f"lander analyse: warning: {path}: unreadable FLIGHT_ENDED: {exc}", file=sys.stderr)
            continue
        if warning:
            print(f"lander analyse: warning: {path}: {warning}", file=sys.stderr)
