"""``lander view BAG``: replay a recorded flight in the student page's 3-D view, with a time slider.

Serves the page (``lander_tools/live/web/``) on ``127.0.0.1`` in replay mode: the bag's states,
as the live bridge would have sent them (:mod:`lander_tools.live.replay`), played at the speed
chosen on the page, or scrubbed with the slider. Runs until Ctrl-C. See docs/live.md.
"""
from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path

DEFAULT_PORT = 8767


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", metavar="BAG", type=Path, help="rosbag2 folder (or .mcap file) of a flight")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"the page's HTTP port (default {DEFAULT_PORT}; 0: a free one, printed)")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.page import PageServer
    from lander_tools.live.replay import load

    replay = load(args.bag)  # BagError / ValueError: one line, exit 2 (lander_tools.cli)
    body = json.dumps(replay.page_json()).encode()
    try:
        page = PageServer(args.host, args.port, None, routes={"/replay.json": lambda: body})
    except OSError as exc:
        print(f"lander view: cannot serve on {args.host}:{args.port}: {exc}", file=sys.stderr)
        return 2
    recs = replay.records
    print(f"view: {args.bag} ({len(recs)} states, t = {recs[0]['t']:.2f} .. {recs[-1]['t']:.2f} s, "
          f"scene {replay.scene}) on http://{args.host}:{page.port}/", flush=True)
    if replay.note:
        print(f"lander view: {replay.note}", file=sys.stderr, flush=True)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        stop.wait()
    finally:
        page.close()
    return 0
