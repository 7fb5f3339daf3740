"""The `lander` command line: one subcommand per module in ``lander_tools/commands/``.

A subcommand module ``lander_tools/commands/<name>.py`` exposes::

    def add_arguments(parser: argparse.ArgumentParser) -> None   # declare its options
    def run(args: argparse.Namespace) -> int                     # do it; return the exit code

Only the module of the subcommand being run is imported, so ``lander --help`` stays fast and a
broken or missing subcommand cannot break the others. Errors are one line and never a traceback
for user mistakes: argparse errors (unknown subcommand/option) exit 2, and a ``ValueError`` raised
by a subcommand (bad scene, bad file, bad value) is printed as ``lander <cmd>: <message>``, exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import NoReturn

# Known subcommands and their one-line summaries, in the order --help lists them. A module added
# to lander_tools/commands/ without an entry here is still found (with a generic summary).
SUMMARIES: dict[str, str] = {
    "fly": "fly a scenario: simulator + autopilot on this machine, optionally recorded to a bag",
    "scenes": "list the scenarios that `lander fly` accepts",
    "controllers": "list the controllers, or one controller's parameter table (--markdown for the docs)",
    "design": "control design report for a scenario (linearisation, gains, poles)",
    "analyse": "metrics and plots from recorded flights (bags)",
    "record": "record topics to a rosbag2 bag (MCAP or sqlite3) until Ctrl-C",
    "bench": "run a benchmark from bench/",
    "sweep": "run a parameter sweep without ROS (many flights, in parallel)",
    "live": "serve a running flight live: Foxglove WebSocket server and the student page",
    "view": "replay a recorded flight (bag) in the student page's 3-D view, with a time slider",
    "demand": "set the demand altitude of the running flight (m)",
    "wind": "set the mean wind of the running flight (world frame, m/s)",
    "switch": "switch the running flight's controller (optionally with a parameters file)",
    "throttle": "set the running flight's throttles by hand, all thrusters or one (0..1)",
    "stabiliser": "switch the running flight's attitude stabiliser on or off",
    "parachute": "deploy the running flight's parachute",
    "pause": "pause the running flight",
    "resume": "resume the running flight",
    "start": "start a paused flight once its autopilot is matched both ways (--until-end: wait for its end)",
    "step": "advance the paused flight by N physics steps",
    "reset": "reset the running flight to its scene's start (t = 0)",
    "topics": "list the running flight's topics and their types",
    "echo": "print a topic of the running flight (--once: one message)",
}

EXIT_USAGE = 2
_as_program = False  # main() called as the program (argv from the command line), not in-process


def running_as_program() -> bool:
    """True in a ``lander`` process (``main()`` without argv): a command may then bound its exit."""
    return _as_program


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line (no usage block), exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _command_names() -> list[str]:
    from lander_tools import commands

    found = {m.name for m in pkgutil.iter_modules(commands.__path__) if not m.name.startswith("_")}
    return [n for n in SUMMARIES] + sorted(found - set(SUMMARIES))


def _load(name: str) -> ModuleType:
    """Import the subcommand module; a missing one raises ValueError with a one-line reason."""
    try:
        return importlib.import_module(f"lander_tools.commands.{name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"lander_tools.commands.{name}":
            raise ValueError("not available in this version (lander_tools/commands/"
                             f"{name}.py is missing)") from None
        raise ValueError(f"cannot load: missing module {exc.name!r}") from None


def build_parser(load: str | None = None) -> _Parser:
    """The full parser; only subcommand ``load`` (if any) gets its arguments (import is lazy)."""
    parser = _Parser(
        prog="lander",
        description="Mars lander simulation: fly scenarios, design controllers, analyse flights.",
        epilog="Run 'lander COMMAND --help' for a command's options.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in _command_names():
        summary = SUMMARIES.get(name, f"the '{name}' command")
        p = sub.add_parser(name, help=summary, description=summary[:1].upper() + summary[1:] + ".")
        if name == load:
            module = _load(name)
            module.add_arguments(p)
            p.set_defaults(_run=module.run)
    return parser


def _requested(argv: Sequence[str], names: list[str]) -> str | None:
    """The subcommand named in argv: the first argument not starting with '-'."""
    for arg in argv:
        if not arg.startswith("-"):
            return arg if arg in names else None
    return None


def main(argv: Sequence[str] | None = None) -> int:
    global _as_program
    _as_program = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    name = _requested(argv, _command_names())
    try:
        parser = build_parser(load=name)
    except ValueError as exc:
        print(f"lander {name}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return int(args._run(args) or 0)
    except ValueError as exc:  # user errors (SceneError, InputError, ...) are ValueError subclasses
        message = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        print(f"lander {args.command}: {message}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"lander {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into e.g. `head`, which stopped reading
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 141


if __name__ == "__main__":
    sys.exit(main())
