"""``lander start``: start a flight whose simulator waits paused (``start_paused``) once everyone
who flies it is matched, so that state 1 reaches the autopilot and no lockstep answer is waited out.

    lander start                       # the sim alone: resume as soon as this command is matched
    lander start --autopilot           # also wait until the autopilot and the sim are matched both ways
    lander start --autopilot --until-end   # then wait for the flight's end instant and exit 0

``launch/fly.launch.py`` runs ``lander start --autopilot --until-end``: the launch ends when this
command exits (lander_tools.fly.launch_plan). Exit status: 0 started (and, with --until-end,
ended); 1 the simulator refused to resume; 3 no flight, or not matched within the wait.
"""
from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any

#: Wall seconds to wait for the sim and the autopilot to match each other once both are seen.
MATCH_TIMEOUT = 30.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    add_wait_argument(parser)
    parser.add_argument("--autopilot", action="store_true",
                        help="wait for the autopilot node and until it and the simulator are matched both ways")
    parser.add_argument("--until-end", action="store_true",
                        help="after resuming, wait for the flight's end instant (FLIGHT_ENDED) and exit 0")


def run(args: argparse.Namespace) -> int:
    from std_srvs.srv import Trigger

    from lander_ros.flight_span import FlightEnd, parse_matched
    from lander_tools.live.link import AUTOPILOT_NODE, SIM_NODE, FlightLink, NoFlight
    from lander_tools.live.verbs import EXIT_NO_FLIGHT, EXIT_REFUSED

    def say(text: str, err: bool = False) -> None:
        print(f"lander start: {text}", file=sys.stderr if err else sys.stdout, flush=True)

    with FlightLink("lander_start") as link:
        try:
            link.wait_for_node(SIM_NODE, args.wait)
            if args.autopilot:
                link.wait_for_node(AUTOPILOT_NODE, args.wait)

            def sim_matched() -> dict[str, int]:
                return parse_matched(link.call(Trigger, "/lander/subscribers", Trigger.Request()).message)

            ended = threading.Event()
            ends: list[Any] = []

            def on_event(msg: Any) -> None:
                if msg.kind == msg.FLIGHT_ENDED:
                    ends.append(FlightEnd.from_values(list(msg.values)))
                    ended.set()

            need: dict[str, int] = {}
            if args.until_end:
                need["/lander/events"] = sim_matched().get("/lander/events", 0) + 1
                link.subscribe("/lander/events", "lander_interfaces/msg/FlightEvent", on_event, depth=1000)
            if args.autopilot:
                need["/lander/state"] = max(need.get("/lander/state", 0), 1)
                need["sub:/lander/throttle"] = 1
            waiting = _wait_matched(link, need, args.autopilot, sim_matched, parse_matched, Trigger)
            if waiting:
                say(f"not matched with the flight within {MATCH_TIMEOUT:g} s (still waiting for {waiting})", err=True)
                return EXIT_NO_FLIGHT
            out = link.sim_service("resume")
        except (NoFlight, TimeoutError) as exc:
            say(str(exc), err=True)
            return EXIT_NO_FLIGHT
        if not out.ok:
            say(f"refused by the flight: {out.message}", err=True)
            return EXIT_REFUSED
        say(out.message)
        if not args.until_end:
            return 0
        while not ended.wait(0.1):
            if SIM_NODE not in link.node_names():
                say(f"{SIM_NODE} left the graph before the flight's end", err=True)
                return EXIT_NO_FLIGHT
        say(ends[0].detail())
        return 0


def _wait_matched(link: Any, need: dict[str, int], autopilot: bool, sim_matched: Any, parse_matched: Any,
                  trigger: Any) -> str:
    """Spin until the sim's writers and readers have matched ``need`` (from ``/lander/subscribers``)
    and, with the autopilot, its state reader has matched the sim (``/autopilot/matched``); '' then,
    else what is still waiting after :data:`MATCH_TIMEOUT` s."""
    deadline = time.monotonic() + MATCH_TIMEOUT
    while True:
        have = sim_matched()
        waiting = [f"sim -> {t}" for t, n in need.items() if have.get(t, 0) < n]
        if not waiting and autopilot:
            answer = link.call(trigger, "/autopilot/matched", trigger.Request()).message
            if parse_matched(answer).get("sub:/lander/state", 0) < 1:
                waiting.append("autopilot <- /lander/state")
        if not waiting:
            return ""
        if time.monotonic() > deadline:
            return ", ".join(waiting)
        time.sleep(0.05)
