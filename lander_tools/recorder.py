"""``lander record``: record topics to a rosbag2 bag (our own ``ros2 bag record`` for PyPI ROS).

Run (project venv)::

    ./dev exec python -m lander_tools.recorder -o out/flight          # default topics, MCAP
    ./dev exec python -m lander_tools.recorder -o out/f --storage sqlite3 /lander/state /clock
    ./dev exec python -m lander_tools.recorder -o out/f --all          # every topic seen

Subscriptions are made with ``raw=True``: the CDR bytes go straight into a
``rosbags`` Writer, never deserialised. Topics are discovered by name and type
from the ROS graph (a topic that appears later is picked up when it appears).
The subscription is compatible with every publisher, whatever QoS it offers:
durability VOLATILE (which matches volatile and transient-local writers alike) and
reliability RELIABLE when every publisher seen is reliable, else BEST_EFFORT (which matches
both), with a deep queue so bursts are kept. A volatile reader gets no history: a latched
topic (``/lander/demand_altitude``) is recorded from the moment the recorder is matched, so
``lander fly`` starts a flight only once the recorder is matched on every topic.
The recorder runs in a node and executor thread of its own (the C++
EventsExecutor where available), so it keeps up with the full stack at speed 0
whatever its owner's thread does; the nodes' own deep writer histories
(``lander_ros.delivery``) cover the moments it is descheduled.

The bag is MCAP by default (each connection's message definition embedded as
the schema, so any MCAP reader can decode it) or sqlite3 on request. It is
closed validly on Ctrl-C, SIGTERM, when a watched node leaves the graph, or when
the owner calls :meth:`Recorder.close`; the count of messages written per topic
is reported.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: What ``lander fly`` records by default: everything the sim and the autopilot publish, plus
#: the inputs (wind, demand altitude, throttle) and the clock; the sensors' topics exist only for a
#: scene with sensors.
DEFAULT_TOPICS: tuple[str, ...] = (
    "/clock",
    "/lander/state",
    "/lander/odom",
    "/lander/pose",
    "/lander/throttle",
    "/lander/wind",
    "/lander/demand_altitude",
    "/lander/events",
    "/lander/markers",
    "/autopilot/status",
    "/diagnostics",
    "/lander/sensors/imu",
    "/lander/sensors/star_tracker",
    "/lander/sensors/altimeter",
    "/lander/sensors/doppler",
    "/lander/sensors/ground_fix",
)
#: Subscription (reader history) depth: the messages of one topic waiting for the recorder's callback,
#: and those received after a hole while the reader waits for the writer's repair (up to the writer's
#: 3 s heartbeat later, ``lander_ros.delivery.OUTPUT_DEPTH``): a reliable reader hands messages over in
#: order only. At 2000 a recorder stopped for 2.5 s lost a run of 1063 clock messages with the writers
#: at 10000; it takes as long as the writers' history to overflow it.
QUEUE_DEPTH = 10000


class RecorderError(ValueError):
    """Bad recorder configuration (unknown storage, existing output, bad topic name)."""


@dataclass
class RecorderConfig:
    """What to record and where.

    Attributes
    ----------
    output : Path
        Bag folder to create (must not exist).
    storage : str
        ``"mcap"`` (default) or ``"sqlite3"``.
    topics : tuple of str
        Topic names to record; ignored when ``all_topics``.
    all_topics : bool
        Record every topic that appears (except ``/rosout`` and parameter events).
    meta : dict
        ``custom_data`` written into the bag's metadata (scene, controller, ...).
    """

    output: Path
    storage: str = "mcap"
    topics: tuple[str, ...] = DEFAULT_TOPICS
    all_topics: bool = False
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from lander_tools.bagio import STORAGES

        self.output = Path(self.output)
        if self.storage not in STORAGES:
            raise RecorderError(f"storage {self.storage!r} is not known; choose one of {', '.join(STORAGES)}")
        if self.output.exists():
            raise RecorderError(f"output {self.output} exists already; the recorder never overwrites a bag")
        bad = [t for t in self.topics if not t.startswith("/")]
        if bad:
            raise RecorderError(f"topic names must be absolute (start with '/'): {', '.join(bad)}")


class Recorder:
    """Records topics of a ROS graph into a rosbag2 bag, in a node and executor thread of its own.

    ``owner`` is a node (its context is used; the launcher passes its own) or an rclpy Context.
    The recorder creates the node ``lander_recorder`` there and spins it in a background thread
    with the C++ ``EventsExecutor`` where rclpy has it: a message then costs ~26 us of Python
    instead of ~700 us per pass of the standard executor (measured), and the recorder takes its
    messages whatever the owner's thread is doing, so it keeps up at the full stack's top speed.
    Every use of the bag writer happens in that thread (sqlite3 connections are bound to the
    thread that opened them). Topics are picked up as they appear (a timer there runs
    :meth:`discover` every ``discovery_period`` s). Call :meth:`close` once at the end.
    """

    _SKIP = ("/rosout", "/parameter_events")
    NODE_NAME = "lander_recorder"

    def __init__(self, owner: Any, config: RecorderConfig, discovery_period: float = 0.1, hold: bool = False) -> None:
        import rclpy

        from lander_ros.delivery import events_executor
        from lander_tools.bagio import lander_typestore

        context = getattr(owner, "context", owner)
        self.config = config
        self.typestore = lander_typestore()
        self.writer: Any = None
        self._conns: dict[str, Any] = {}
        self._subs: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        #: Set: messages are taken and dropped, counted in :attr:`dropped` (``hold=True`` starts so):
        #: ``lander record --whole-flight`` matches first and writes from the flight's reset on.
        self.held = threading.Event()
        if hold:
            self.held.set()
        self.dropped: dict[str, int] = {}
        #: Per topic, a test of the raw message: False drops it (counted in :attr:`dropped`), as
        #: while held. ``lander record --whole-flight`` drops the sim's reports of the old flight.
        self.accept: dict[str, Callable[[bytes], bool]] = {}
        self.closed = False
        self._error: BaseException | None = None
        self.node = rclpy.create_node(self.NODE_NAME, context=context)
        self._stopping = threading.Event()
        self._opened = threading.Event()
        self._executor = events_executor(context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        self._thread.start()
        self._opened.wait()
        error = self._startup_error()
        if error is not None:  # the bag could not be created: nothing to record into
            self._shutdown_node()
            raise error
        self._timer = self.node.create_timer(discovery_period, self.discover)

    def _startup_error(self) -> BaseException | None:
        """What the recorder's thread met creating the bag (None: the bag is open)."""
        return self._error

    def _run(self) -> None:
        """The recorder thread: open the bag, serve the recorder's node until :meth:`close` (or the
        context ends), close the bag."""
        from rosbags.rosbag2 import StoragePlugin, Writer

        try:
            plugin = StoragePlugin.MCAP if self.config.storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer(self.config.output, version=9, storage_plugin=plugin)
            for k, v in self.config.meta.items():
                self.writer.set_custom_data(str(k), str(v))
            self.writer.open()
        except Exception as exc:  # noqa: BLE001 - handed to the constructor, which raises it
            self._error = exc
            return
        finally:
            self._opened.set()
        try:
            self.discover()
            while not self._stopping.is_set():
                self._executor.spin_once(timeout_sec=0.1)
        except Exception:  # noqa: BLE001 - the context was shut down under us: recording ends
            if not self._stopping.is_set():
                self.node.get_logger().warning("recorder executor stopped: the ROS context was shut down")
        finally:
            self.closed = True
            try:
                self.writer.close()
            except Exception as exc:  # noqa: BLE001 - re-raised by close() in the owner's thread
                self._error = exc

    # --- discovery ---------------------------------------------------------------------------

    def wanted(self, topic: str) -> bool:
        if self.config.all_topics:
            return not topic.startswith(self._SKIP)
        return topic in self.config.topics

    def discover(self) -> None:
        """Subscribe to every wanted topic now visible in the graph and not yet subscribed.

        Runs in the recorder thread (its timer); called from another thread it does nothing,
        the timer picks new topics up within a discovery period (poll :meth:`subscribed`)."""
        if self.closed or threading.current_thread() is not self._thread:
            return
        if not self.config.all_topics and all(t in self._subs for t in self.config.topics):
            return  # everything asked for is recorded: no graph query (10 per second otherwise)
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self._subs or not self.wanted(topic) or not types:
                continue
            self._subscribe(topic, types[0])

    def _qos(self, topic: str) -> Any:
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        pubs = self.node.get_publishers_info_by_topic(topic)
        reliable = all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in pubs)
        # A reliable reader would not match a best-effort writer, a transient-local reader not a
        # volatile one (a user's `ros2 topic pub` or default-QoS publisher): VOLATILE always, and
        # RELIABLE only while no publisher is best-effort, so every publisher is matched.
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=QUEUE_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.VOLATILE,
        )

    def _subscribe(self, topic: str, msgtype: str) -> None:
        from lander_tools.bagio import BagError, message_class, register_msgtype

        try:
            cls = message_class(msgtype)
            register_msgtype(self.typestore, msgtype)
        except (ImportError, AttributeError, BagError) as exc:
            self.node.get_logger().warning(f"not recording {topic}: type {msgtype} unavailable ({exc})")
            self._subs[topic] = None
            return
        self._conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.typestore)
        self.counts[topic] = 0
        self._subs[topic] = self.node.create_subscription(
            cls, topic, self._writer_for(topic), self._qos(topic), raw=True
        )

    def _writer_for(self, topic: str) -> Callable[[bytes], None]:
        conn = self._conns[topic]
        write = self.writer.write
        counts, dropped, held, accept = self.counts, self.dropped, self.held, self.accept
        now = time.time_ns

        def on_message(data: bytes) -> None:
            test = accept.get(topic)
            if held.is_set() or (test is not None and not test(data)):
                dropped[topic] = dropped.get(topic, 0) + 1
                return
            # Receive time (wall clock, ns); analysis maps it to sim time through /clock. Runs in
            # the recorder thread, as every other use of the writer: no lock needed.
            write(conn, now(), data)
            counts[topic] += 1

        return on_message

    def matched(self, topic: str) -> int:
        """Publishers the recorder's reader on ``topic`` has matched (0: not subscribed yet)."""
        sub = self._subs.get(topic)
        return 0 if sub is None else sub.get_publisher_count()

    def subscribed(self) -> list[str]:
        # list() copies in one step under the GIL: the recorder thread may be adding topics.
        return sorted(t for t, s in list(self._subs.items()) if s is not None)

    def wait_quiet(self, quiet: float, limit: float, *, skip: tuple[str, ...] = (),
                   pause: Callable[[float], Any] = time.sleep) -> None:
        """Return once no message (written, or dropped while :attr:`held`) has arrived on any topic
        but ``skip`` for ``quiet`` wall seconds, or after ``limit`` s. ``pause(s)`` passes the time
        between looks (the launcher spins its executor there)."""
        def total() -> int:
            return sum(n for t, n in [*list(self.counts.items()), *list(self.dropped.items())] if t not in skip)

        end = time.monotonic() + limit
        last, since = total(), time.monotonic()
        while time.monotonic() < end and time.monotonic() - since < quiet:
            pause(0.02)
            now = total()
            if now != last:
                last, since = now, time.monotonic()

    # --- end ---------------------------------------------------------------------------------

    def close(self) -> dict[str, int]:
        """Stop recording and write the bag's index and metadata; returns messages per topic.

        What has not reached the recorder's callbacks by now is not recorded: an owner that
        stopped the publishers first waits until the counts stop growing (the launcher does).
        Custom data set on :attr:`writer` before this call goes into the metadata."""
        self._stopping.set()
        self._thread.join()  # the thread closes the bag on its way out
        self._shutdown_node()
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        return dict(self.counts)

    def _shutdown_node(self) -> None:
        try:
            self._executor.shutdown()
            self.node.destroy_node()
        except Exception:  # noqa: BLE001 - the context may already be gone at shutdown
            pass

    def summary(self) -> str:
        """One line per topic: messages written."""
        width = max((len(t) for t in self.counts), default=5)
        lines = [f"bag {self.config.output} ({self.config.storage}):"]
        lines += [f"  {t:<{width}}  {n:>8d} messages" for t, n in sorted(self.counts.items())]
        lines.append(f"  {'total':<{width}}  {sum(self.counts.values()):>8d} messages")
        return "\n".join(lines)


def node_alive(node: Any, full_name: str) -> bool:
    """True while a node called ``full_name`` (e.g. ``/lander_sim``) is in the graph."""
    for name, ns in node.get_node_names_and_namespaces():
        if (ns.rstrip("/") + "/" + name) == full_name:
            return True
    return False


def build_parser(parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The recorder's options (``lander record`` adds them to its sub-parser)."""
    p = parser or argparse.ArgumentParser(prog="lander record", description=__doc__.split("\n\n")[0])
    p.add_argument("topics", nargs="*", metavar="TOPIC", help=f"topics to record (default: {' '.join(DEFAULT_TOPICS)})")
    p.add_argument("-o", "--output", required=True, metavar="BAG", help="bag folder to create (must not exist)")
    p.add_argument("--storage", default="mcap", choices=("mcap", "sqlite3"), help="bag storage (default mcap)")
    p.add_argument("--all", action="store_true", help="record every topic that appears")
    p.add_argument(
        "--stop-when-gone",
        metavar="NODE",
        help="close the bag when this node (e.g. /lander_sim) leaves the graph after having been seen",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    """Stand-alone recorder: runs until Ctrl-C / SIGTERM (or the watched node is gone)."""
    return record(build_parser().parse_args(sys.argv[1:] if argv is None else argv))


def record(args: argparse.Namespace) -> int:
    """Record as ``args`` (from :func:`build_parser`) say until Ctrl-C / SIGTERM; 0, or 2 on bad options."""
    try:
        config = RecorderConfig(
            Path(args.output), args.storage, tuple(args.topics) or DEFAULT_TOPICS, bool(args.all)
        )
    except RecorderError as exc:
        print(f"lander record: {exc}", file=sys.stderr)
        return 2

    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()

    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rec = Recorder(rclpy.get_default_context(), config)
    seen = False
    try:
        # The recorder works in its own thread; this one only waits for the end. The watched
        # node is looked up every 0.1 s (a graph query, so not once per message).
        while not stop.wait(0.1) and rclpy.ok():
            if args.stop_when_gone:
                alive = node_alive(rec.node, args.stop_when_gone)
                seen = seen or alive
                if seen and not alive:
                    rec.node.get_logger().info(f"{args.stop_when_gone} left the graph: closing the bag")
                    break
    except KeyboardInterrupt:
        pass
    finally:
        rec.close()
        print(rec.summary())
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
