"""What every CLI verb does around its one action: find the flight, act, print one line.

Exit status: 0 done; 1 refused by the flight (the node's reason is printed); 3 no flight running
(the simulator or the needed node not seen within :data:`lander_tools.live.link.DISCOVERY_TIMEOUT`
s, or a service that does not answer). Errors are one line on stderr: ``lander VERB: ...``.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from lander_tools.live.link import (
    DISCOVERY_TIMEOUT,
    SIM_NODE,
    FlightLink,
    NoFlight,
    Outcome,
)

EXIT_REFUSED = 1
EXIT_NO_FLIGHT = 3
#: Wall seconds to wait for the nodes of a flight the user's run file says is running (discovery
#: takes up to ~3 s with several processes starting on 2 cores; more under heavier load).
RUNNING_FLIGHT_WAIT = 30.0
#: Wall seconds the link's ROS teardown may take in a ``lander`` process (normally milliseconds).
CLOSE_TIMEOUT = 10.0


def add_wait_argument(parser: argparse.ArgumentParser) -> None:
    """``--wait S``: how long to look for the flight's nodes (every verb has it)."""
    parser.add_argument("--wait", type=float, default=DISCOVERY_TIMEOUT, metavar="S",
                        help=f"wall seconds to wait for the flight's nodes to appear (default {DISCOVERY_TIMEOUT:g})")


def run_verb(verb: str, action: Callable[[FlightLink], Outcome], needs: str = SIM_NODE,
             wait: float = DISCOVERY_TIMEOUT) -> int:
    """Open a link, wait up to ``wait`` s for the simulator and the node ``needs``, run ``action``;
    print its outcome; return the exit status.

    The line is printed before the link's ROS teardown, and in a ``lander`` process that teardown
    is bounded (:func:`_bounded_close`): Fast DDS can deadlock destroying a participant while it
    removes a remote one (seen in CI: a verb hung in ``destroy_node`` as other verbs exited)."""
    from lander_tools.fly.domain import attach_env

    found = attach_env()  # the user's own flight's domain (its run file), this machine only by default
    if found.note:
        print(f"lander {verb}: {found.note}", file=sys.stderr, flush=True)
    if found.flight is not None and wait == DISCOVERY_TIMEOUT:
        wait = RUNNING_FLIGHT_WAIT  # it runs (its run file says so): a loaded machine only slows discovery
    link = FlightLink(f"lander_{verb}")
    try:
        try:
            link.wait_for_node(SIM_NODE, wait)
            if needs != SIM_NODE:
                link.wait_for_node(needs, wait)
            out = action(link)
        except (NoFlight, TimeoutError) as exc:
            print(f"lander {verb}: {exc}", file=sys.stderr, flush=True)
            return EXIT_NO_FLIGHT
        if not out.ok:
            print(f"lander {verb}: refused by the flight: {out.message}", file=sys.stderr, flush=True)
            return EXIT_REFUSED
        extra = "".join(f", {k} {v}" for k, v in (out.values or {}).items())
        print(f"lander {verb}: {out.message or 'ok'}{extra}", flush=True)
        return 0
    finally:
        _bounded_close(link)


def _bounded_close(link: FlightLink) -> None:
    """Close ``link``; in the ``lander`` program (not in-process callers) a stuck teardown ends the
    process after :data:`CLOSE_TIMEOUT` s with the threads' stacks on stderr. faulthandler's
    watchdog is a C thread: the stuck call holds the GIL, so no Python-level wait could end it."""
    import faulthandler

    from lander_tools import cli

    guard = cli.running_as_program()
    if guard:
        faulthandler.dump_traceback_later(CLOSE_TIMEOUT, exit=True)
    try:
        link.close()
    finally:
        if guard:
            faulthandler.cancel_dump_traceback_later()
