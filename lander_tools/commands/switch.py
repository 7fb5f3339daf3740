"""``lander switch NAME [--params FILE]``: swap the running autopilot's controller.

Calls ``/autopilot/switch_controller`` with the controller's parameters from a YAML file (a
mapping). A refused switch (unknown name, bad gains) prints the node's reason, exit 1.
"""
import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("name", metavar="NAME", help="controller plug-in name")
    parser.add_argument("--params", type=Path, metavar="FILE", help="YAML mapping of the controller's parameters")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.link import AUTOPILOT_NODE
    from lander_tools.live.verbs import run_verb

    text = ""
    if args.params is not None:
        try:
            text = args.params.read_text()
        except OSError as exc:
            raise ValueError(f"--params {args.params}: cannot read ({exc.strerror})") from None
    return run_verb("switch", lambda link: link.switch_controller(args.name, text), needs=AUTOPILOT_NODE, wait=args.wait)
