"""``lander echo TOPIC [--once]``: print a running flight's messages as JSON lines (``ros2 topic echo``).

Waits for the topic to appear (no flight / no such topic: exit 3); ``--once`` exits 0 after
the first message (exit 3 after ``--timeout`` s without one: a paused flight publishes no state),
else runs until Ctrl-C.
"""
from __future__ import annotations

import argparse
from typing import Any

#: [s] how long ``--once`` waits for its message unless told: a flight publishes its state every
#: control period (0.1 s in the scenes), and a paused one not at all
ONCE_TIMEOUT = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("topic", metavar="TOPIC", help="absolute topic name, e.g. /lander/state")
    parser.add_argument("--once", action="store_true", help="print one message and exit")
    parser.add_argument("--timeout", type=float, default=ONCE_TIMEOUT, metavar="S",
                        help=f"with --once: give up after S wall seconds without a message (exit 3; default "
                             f"{ONCE_TIMEOUT:g})")
    add_wait_argument(parser)


def run(args: argparse.Namespace) -> int:
    import json
    import threading

    from lander_tools.live.link import Outcome, message_to_dict
    from lander_tools.live.verbs import run_verb

    if not args.topic.startswith("/"):
        raise ValueError(f"topic names are absolute (start with '/'), got {args.topic!r}")

    def echo(link: Any) -> Outcome:
        msgtype = link.topic_type(args.topic, args.wait)
        got, done = threading.Event(), threading.Event()

        def show(msg: Any) -> None:
            if args.once and got.is_set():
                return
            try:
                print(json.dumps(message_to_dict(msg)), flush=True)
            except BrokenPipeError:  # piped into e.g. `head`, which has stopped reading
                done.set()
            got.set()

        link.subscribe(args.topic, msgtype, show)
        if args.once:
            if not got.wait(args.timeout):
                raise TimeoutError(f"no message on {args.topic} within {args.timeout:g} s (a paused flight "
                                   "publishes no state: `lander step` or `lander resume` moves it on)")
            return Outcome(True, f"one {msgtype} message")
        done.wait()  # until Ctrl-C, or the reader of our output is gone
        return Outcome(True, "")

    return run_verb("echo", echo, wait=args.wait)
