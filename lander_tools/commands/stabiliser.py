"""``lander stabiliser on|off``: switch the running simulator's attitude stabiliser
(``/lander/set_stabiliser``, docs/sim_node.md): on, it holds the lander upright as the original
program's does, whatever the thrusters do. Prints the service's answer; no flight: exit 3.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("state", choices=("on", "off"), help="on or off")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.verbs import run_verb

    return run_verb("stabiliser", lambda link: link.sim_service("set_stabiliser", data=args.state == "on"),
                    wait=args.wait)
