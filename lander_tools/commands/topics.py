"""``lander topics``: the running flight's topics and their types (``ros2 topic list -t``).

The list is taken once the simulator's own topics (its outputs and inputs) are all in the graph,
waiting up to ``--wait`` s more once the simulator is seen (at most twice ``--wait`` in all): a
node is discovered before its endpoints, and a list taken the moment the simulator appears can
lack some of them. Any still missing then are named on stderr.
No flight running: exit 3 after waiting for the simulator.
"""
from __future__ import annotations

import argparse
from typing import Any


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    import sys

    from lander_ros.flight_span import COUNTED_TOPICS, SIM_INPUT_TOPICS
    from lander_tools.live.link import Outcome
    from lander_tools.live.verbs import run_verb

    def show(link: Any) -> Outcome:
        rows, missing = link.await_topics((*COUNTED_TOPICS, *SIM_INPUT_TOPICS), args.wait)
        if missing:
            print(f"lander topics: the simulator's {', '.join(missing)} not seen within {args.wait:g} s",
                  file=sys.stderr, flush=True)
        width = max((len(n) for n, _ in rows), default=0)
        for name, types in rows:
            print(f"{name:<{width}}  {', '.join(types)}")
        return Outcome(True, f"{len(rows)} topics")

    return run_verb("topics", show, wait=args.wait)
