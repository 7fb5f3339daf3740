"""``lander step N``: advance the paused simulator by exactly N physics steps (``/lander/step``).

Refused (running, N = 0): exit 1 with the node's message; no flight: exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("steps", type=int, metavar="N", help="physics steps (the simulator must be paused)")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.verbs import run_verb

    if not 0 <= args.steps < 2**32:
        raise ValueError(f"N must be an integer in 0..{2**32 - 1}, got {args.steps}")
    return run_verb("step", lambda link: link.sim_service("step", steps=args.steps), wait=args.wait)
