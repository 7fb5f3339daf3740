"""``lander record -o BAG [--storage mcap|sqlite3] [--all] [--stop-when-gone NODE] [--live [--port P]] [TOPIC ...]``.

Records topics into a rosbag2 bag until Ctrl-C / SIGTERM (our own ``ros2 bag record`` for ROS 2
from PyPI): a thin wrapper over :mod:`lander_tools.recorder`. Exit status 0, or 2 for a bad option
(existing output, unknown storage, relative topic name). Heavy imports (rclpy) happen in :func:`run`.
"""

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.recorder import build_parser

    build_parser(parser)
    parser.add_argument("--live", action="store_true",
                        help="also serve the flight live: Foxglove server and student page (docs/live.md)")
    parser.add_argument("--port", type=int, default=8765, metavar="P",
                        help="with --live: Foxglove WebSocket port (student page on P + 1)")


def run(args: argparse.Namespace) -> int:
    from lander_tools.recorder import record

    if not args.live:
        return record(args)
    import subprocess

    from lander_tools.live.bridge import command

    # `lander live` beside the recorder, in its own process (it dies with this one).
    bridge = subprocess.Popen(command(args.port, args.port + 1 if args.port else 0))
    try:
        return record(args)
    finally:
        if bridge.poll() is None:
            bridge.terminate()
        bridge.wait(10)
