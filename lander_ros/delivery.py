"""Delivery of the nodes' outputs: the QoS of what they publish and an orderly end that loses nothing.

Shared by the simulator and the autopilot node (and anything else that publishes the control
loop's topics), so both keep the same promises to a recorder:

* :data:`OUTPUT_QOS`: reliable, with a writer history deep enough that a subscriber stalled for a
  moment (a recorder descheduled on a loaded machine) still receives every message;
* :func:`flush`: before a node process exits, wait until its subscribers acknowledged what it
  published (a destroyed reliable writer drops whatever it has not delivered yet);
* :func:`install_stop_handlers`: SIGINT/SIGTERM end the node's loop instead of rclpy shutting the
  context down at once, which would make that flush impossible;
* :func:`run_node_process`: the whole life of a node process built on those (both nodes' ``main``);
* :func:`events_executor`: the cheapest executor per message, for a loop that needs one thread.
"""
from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable, Iterable
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

#: Writer history of every output. A reliable KEEP_LAST writer keeps its last ``depth`` messages for
#: a subscriber that has not acknowledged them yet and drops older ones unseen, so the depth must
#: cover rate x (the slowest subscriber's longest stall + the time a repair takes). The repair is
#: the slow part: a message the transport dropped while a subscriber was descheduled (its
#: shared-memory port full) is re-sent only after the writer's next heartbeat has made the reader
#: ask for it, and Fast DDS's periodic heartbeat is 3 s. Measured (docs/reliability.md, "Delivery"):
#: with the old depth of 1000 a recorder stopped for 1 s lost 1-10 messages a stop, delivered up to
#: 2.9 s late; the de-orbit scenes' coast runs up to ~120x real time at 10 Hz (deorbit, from a bag's
#: receive times), ~1200 messages/s per topic, so 1000 covered 0.8 s. 10000 covers 3 s of repair
#: plus a 5 s stall at that rate (plus 1 s at 2500/s, the 50 Hz free-running top speed) and costs
#: memory only for messages not yet acknowledged (~3 MB more RSS per node at the peak of a de-orbit
#: flight). KEEP_LAST never blocks the publisher on its history (a stall of seconds can still slow
#: the other subscribers through the shared-memory transport: docs/reliability.md).
OUTPUT_DEPTH = 10000
OUTPUT_QOS = QoSProfile(depth=OUTPUT_DEPTH, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: Wall seconds a node waits in all at exit for its subscribers to acknowledge its last messages
#: (a dead subscriber, still matched until its lease expires, would otherwise hold the exit up).
FLUSH_TIMEOUT = 1.0


def flush(publishers: Iterable[Any], timeout: float = FLUSH_TIMEOUT) -> bool:
    """Wait until every subscriber acknowledged everything ``publishers`` published, at most
    ``timeout`` wall seconds in all; True if they all did."""
    deadline = time.monotonic() + timeout
    ok = True
    for pub in publishers:
        left = max(0.0, deadline - time.monotonic())
        ok = pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))) and ok
    return ok


def install_stop_handlers(request_stop: Callable[[], None]) -> None:
    """SIGINT and SIGTERM call ``request_stop`` (the node's loop ends cleanly, then it flushes);
    a second signal raises KeyboardInterrupt, so a node stuck somewhere still ends.

    Use with ``rclpy.init(..., signal_handler_options=SignalHandlerOptions.NO)``."""
    received: list[int] = []

    def on_signal(signum: int, _frame: Any) -> None:
        received.append(signum)
        if len(received) > 1:
            raise KeyboardInterrupt
        request_stop()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)


def events_executor(context: Any = None) -> Any:
    """rclpy's C++ EventsExecutor where this rclpy has it (about 3x cheaper per pass than the
    standard executor, and ~26 us of Python per message against ~700 us: measured), else the
    standard single-threaded one. ``context``: None for the default context."""
    try:
        from rclpy.experimental.events_executor import EventsExecutor
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def run_node_process(prog: str, argv: list[str], make_node: Callable[[], Any],
                     make_executor: Callable[[], Any]) -> int:
    """A node process from start to exit; returns its exit status.

    rclpy is initialised without its signal handlers; SIGINT/SIGTERM call the node's
    ``request_stop()`` (:func:`install_stop_handlers`), which ends its ``run(executor)``; then its
    last messages are flushed (``flush()``) before the context goes down. A ValueError or
    ParameterException out of the node (a bad configuration: unknown parameter, bad scene, ...)
    is one line ``prog: message`` on stderr and status 2. A crash in native code (a segmentation
    fault in a compiled extension) prints the Python stack of every thread on stderr first
    (:mod:`faulthandler`), so the launcher's log says where the node died.
    """
    import faulthandler

    faulthandler.enable()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = make_node()
        install_stop_handlers(node.request_stop)
        executor = make_executor()
        executor.add_node(node)
        node.run(executor)
        node.flush()
    except (ValueError, ParameterException) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
