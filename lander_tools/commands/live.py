"""``lander live [--port P]``: serve the running flight to Foxglove and the student page.

Attaches to a flight in this ROS domain (like ``lander record``); ``lander fly SCENE --live``
starts the same process with the flight. Runs until Ctrl-C. See docs/live.md.
"""
import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.bridge import build_parser

    build_parser(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.fly.domain import attach_env

    note = attach_env().note  # the user's own flight's domain (its run file), this machine only by default
    if note:
        print(f"lander live: {note}", file=sys.stderr, flush=True)
    from lander_tools.live.bridge import serve

    return serve(args)
