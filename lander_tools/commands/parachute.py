"""``lander parachute``: deploy the running lander's parachute (``/lander/deploy_parachute``,
docs/sim_node.md). The simulator refuses a deployment it cannot make (the scene has no parachute
model, it is already out or was lost): exit 1 with its reason; no flight: exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.verbs import run_verb

    return run_verb("parachute", lambda link: link.sim_service("deploy_parachute"), wait=args.wait)
