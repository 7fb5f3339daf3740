"""``lander analyse BAG...``: metrics and plots from recorded flights (bags).

One bag: a metrics table (or ``--json``) and, with ``--out``, the standard plots.
Two or more: the same side by side, metric differences against the first bag and
overlaid plots. A damaged bag is read as far as it goes, with a warning; an
unreadable one is a one-line error (exit 2), never a traceback.
Heavy imports (numpy, matplotlib, rosbags) happen in :func:`run`.
"""

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", metavar="BAG", nargs="+", type=Path,
                        help="rosbag2 folder(s) (or .mcap files) recorded by 'lander fly --record'")
    parser.add_argument("--json", action="store_true", help="print the metrics as JSON instead of a table")
    parser.add_argument("--out", metavar="DIR", type=Path, help="write plots (PNG) to this folder")
    parser.add_argument("--prefix", default="flight", help="file name prefix of the plots (default: flight)")
    parser.add_argument("--band", type=float, default=0.5, metavar="M",
                        help="smallest settling band, m (default 0.5; else 2%% of the step)")


def run(args: argparse.Namespace) -> int:
    import sys
    import warnings

    from lander_tools.analysis import Flight, metrics, table, to_json, write_plots
    from lander_tools.bagio import BagError, BagWarning, read_bag

    flights = []
    for path in args.bags:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", BagWarning)
            try:
                bag = read_bag(path)
                flights.append(Flight.from_bag(bag, name=_name(path, [f.name for f in flights])))
                _print_span(path, bag)
            except BagError as exc:
                print(f"lander analyse: {exc}", file=sys.stderr)
                return 2
        for w in caught:
            print(f"lander analyse: warning: {w.message}", file=sys.stderr)
    all_metrics = [metrics(f, band_min=args.band) for f in flights]
    print(to_json(all_metrics) if args.json else table(all_metrics))
    if args.out is not None:
        for p in write_plots(flights, args.out, args.prefix):
            print(f"wrote {p}", file=sys.stderr)
    return 0


def _name(path: Path, taken: list[str]) -> str:
    name = path.name if path.name else str(path)
    return name if name not in taken else f"{name}#{len(taken) + 1}"


def _print_span(path: Path, bag) -> None:
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
