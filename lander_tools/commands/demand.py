"""``lander demand ALT``: set the running autopilot's demand altitude [m].

Through the autopilot's own parameter service (the door its ``/lander/demand_altitude`` topic
uses): a refused value (negative, not finite) prints the node's reason, exit 1; no flight, exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("altitude", type=float, metavar="ALT", help="demand altitude above the surface, m")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.link import AUTOPILOT_NODE
    from lander_tools.live.verbs import run_verb

    return run_verb("demand", lambda link: link.set_demand(args.altitude), needs=AUTOPILOT_NODE, wait=args.wait)
