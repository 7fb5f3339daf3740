"""``lander record -o BAG [--storage mcap|sqlite3] [--all] [--stop-when-gone NODE] [--whole-flight
[--duration S] [--wait S]] [--live [--port P]] [TOPIC ...]``.

Records topics into a rosbag2 bag until Ctrl-C / SIGTERM (our own ``ros2 bag record`` for ROS 2
from PyPI): a thin wrapper over :mod:`lander_tools.recorder`. Exit status 0, or 2 for a bad option
(existing output, unknown storage, relative topic name). ``--whole-flight`` restarts the running
flight from t = 0 and records it to its end, checked (:mod:`lander_tools.whole_flight`: exit 1 no
flight, 3 a message missing). Heavy imports (rclpy) happen in :func:`run`.
"""

import argparse
import sys
from collections.abc import Callable


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.recorder import build_parser
    from lander_tools.whole_flight import add_arguments as add_whole_flight_arguments

    build_parser(parser)
    add_whole_flight_arguments(parser)
    parser.add_argument("--live", action="store_true",
                        help="also serve the flight live: Foxglove server and student page (docs/live.md)")
    parser.add_argument("--port", type=int, default=8765, metavar="P",
                        help="with --live: Foxglove WebSocket port (student page on P + 1)")


def run(args: argparse.Namespace) -> int:
    from lander_tools.fly.domain import attach_env

    note = attach_env().note  # the user's own flight's domain (its run file), this machine only by default
    if note:
        print(f"lander record: {note}", file=sys.stderr, flush=True)
    if args.duration is not None and not args.whole_flight:
        print("lander record: --duration needs --whole-flight (a recorder alone cannot end a flight)", file=sys.stderr)
        return 2
    if args.start and not args.whole_flight:
        print("lander record: --start needs --whole-flight (it resumes the flight after the recorder's reset)",
              file=sys.stderr)
        return 2
    if not args.live:
        return _record(args)
    import subprocess

    from lander_tools.live.bridge import command

    # `lander live` beside the recorder, in its own process (it dies with this one).
    bridges: list[subprocess.Popen[bytes]] = []

    def start_bridge() -> None:
        bridges.append(subprocess.Popen(command(args.port, args.port + 1 if args.port else 0)))

    try:
        if args.whole_flight:  # the bridge joins after the reset, so it is no reader the protocol waits for
            return _record(args, on_started=start_bridge)
        start_bridge()
        return _record(args)
    finally:
        for bridge in bridges:
            if bridge.poll() is None:
                bridge.terminate()
            bridge.wait(10)


def _record(args: argparse.Namespace, on_started: Callable[[], None] | None = None) -> int:
    """The recorder alone, or with ``--whole-flight`` the flight restarted and recorded whole."""
    if args.whole_flight:
        from lander_tools.whole_flight import record_whole_flight

        return record_whole_flight(args, on_started=on_started)
    from lander_tools.recorder import record

    return record(args)
