"""``lander wind X Y Z``: set the mean wind of the running flight (world frame ``mars``, m/s).

Published on ``/lander/wind``; the simulator validates it. A refusal (non-finite) comes back as
its INPUT_REJECTED event within a short window and is printed, exit 1; no flight, exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    for axis in "XYZ":
        parser.add_argument(axis.lower(), type=float, metavar=axis, help=f"wind {axis.lower()} component, world frame, m/s")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.verbs import run_verb

    return run_verb("wind", lambda link: link.publish_wind((args.x, args.y, args.z)), wait=args.wait)
