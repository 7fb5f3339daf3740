"""``lander reset``: call the running simulator's ``/lander/reset`` service (docs/sim_node.md).

Prints the service's answer; refused: exit 1 with its message; no flight: exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.verbs import run_verb

    return run_verb("reset", lambda link: link.sim_service("reset"), wait=args.wait)
