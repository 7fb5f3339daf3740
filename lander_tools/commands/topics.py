"""``lander topics``: the running flight's topics and their types (``ros2 topic list -t``).

No flight running: exit 3 after waiting for the simulator.
"""
import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.link import Outcome
    from lander_tools.live.verbs import run_verb

    def show(link):
        rows = link.topics()
        width = max((len(n) for n, _ in rows), default=0)
        for name, types in rows:
            print(f"{name:<{width}}  {', '.join(types)}")
        return Outcome(True, f"{len(rows)} topics")

    return run_verb("topics", show, wait=args.wait)
