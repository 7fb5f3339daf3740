"""``lander record -o BAG [--storage mcap|sqlite3] [--all] [--stop-when-gone NODE] [TOPIC ...]``.

Records topics into a rosbag2 bag until Ctrl-C / SIGTERM (our own ``ros2 bag record`` for ROS 2
from PyPI): a thin wrapper over :mod:`lander_tools.recorder`. Exit status 0, or 2 for a bad option
(existing output, unknown storage, relative topic name). Heavy imports (rclpy) happen in :func:`run`.
"""

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.recorder import build_parser

    build_parser(parser)


def run(args: argparse.Namespace) -> int:
    from lander_tools.recorder import record

    return record(args)
