"""``lander switch NAME [--params FILE]`` / ``lander switch --gains FILE``: swap the running
autopilot's controller.

Calls ``/autopilot/switch_controller`` with the controller's parameters from a YAML file (a
mapping), or with the controller and gains of a gains file (``lander design SCENE --write FILE``,
lander_tools.gains): the gains designed, flown from the next state on. A refused switch (unknown
name, bad gains) prints the node's reason, exit 1.
"""
import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("name", metavar="NAME", nargs="?", help="controller plug-in name (with --gains: the file's)")
    parser.add_argument("--params", type=Path, metavar="FILE", help="YAML mapping of the controller's parameters")
    parser.add_argument("--gains", type=Path, metavar="FILE",
                        help="a gains file ('lander design SCENE --write FILE'): switch to its controller and gains")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.link import AUTOPILOT_NODE
    from lander_tools.live.verbs import run_verb

    text = ""
    name = args.name
    if args.gains is not None:
        from lander_tools.gains import controller_params_text, read_gains

        if args.params is not None:
            raise ValueError("--params and --gains: give one of them (a gains file holds the parameters)")
        controller, params = read_gains(args.gains)
        if name is not None and name != controller:
            raise ValueError(f"--gains {args.gains} holds gains for controller {controller!r}, not {name!r}")
        name = controller
        text = controller_params_text(params)
    elif name is None:
        raise ValueError("NAME: give the controller to switch to (or --gains FILE)")
    elif args.params is not None:
        try:
            text = args.params.read_text()
        except OSError as exc:
            raise ValueError(f"--params {args.params}: cannot read ({exc.strerror})") from None
    return run_verb("switch", lambda link: link.switch_controller(name, text), needs=AUTOPILOT_NODE, wait=args.wait)
