"""Which publishers' throttles a launched flight's simulator takes: the flight's own, never a stranger's.

Plain Python (no rclpy). A flight started by ``lander fly`` gives its simulator a ``flight_id``
(docs/sim_node.md, "Parameters"); the simulator then takes ``/lander/throttle`` only from the
flight's nodes (:data:`FLIGHT_NODES`: its autopilot, its launcher ``/lander_fly``) and the user's
``lander`` verbs (nodes ``/lander_*``, e.g. ``lander live``'s throttles). A node name belongs to
one publisher: the first one heard from in the flight owns it while it is in the graph, and a
second publisher under the same name (another flight's autopilot, started in the same ROS domain
and answering this flight's states) is a stranger. So is any other node (``ros2 topic pub``, a
script of one's own). A stranger's messages are refused and counted; its first one is announced in
one line naming it (:meth:`InputGuard.refusal`). The launcher names the flight's nodes in the
simulator's ``flight_nodes`` parameter (a flight without autopilot: ``/lander_fly`` alone, so
another flight's autopilot cannot command it).

The sender of a message is its publisher's GID, which rclpy hands to a subscription callback
taking two arguments (``MessageInfo['publisher_gid']``), and the graph names the node of each
publisher GID (``Node.get_publishers_info_by_topic``). The graph is discovered apart from the
endpoints' matching, so a message can come before the graph lists its publisher: until one of the
flight's own publishers has been heard such a message is taken (it may be the autopilot's first
answer), afterwards it is refused and counted until the graph names its sender. Residual: a verb's
first message, sent the moment it is matched, can be refused that way.

The autopilot of a launched flight (its ``flight_id`` set) takes ``/lander/state`` the same way,
from its flight's ``/lander_sim`` only (the first heard), so another flight's simulator in the
domain does not steer it either.

Without a ``flight_id`` (nodes run by hand or by ``ros2 launch``) every publisher is taken, as
docs/sim_node.md and docs/autopilot_node.md describe.
"""
from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

#: Node names whose one publisher each is the flight's own (the ``flight_nodes`` parameter's default).
FLIGHT_NODES: tuple[str, ...] = ("/autopilot", "/lander_fly")
#: Prefix of the user's ``lander`` verbs' nodes (``lander_tools.live.link.FlightLink``): taken.
VERB_PREFIX = "/lander_"
#: The node name rmw_fastrtps gives an endpoint whose node it does not know yet.
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
#: The rejection kind a stranger's throttles are counted under (the sim's diagnostics).
STRANGER_KIND = "throttle.stranger"


def gid_of(info: Any) -> bytes | None:
    """The publisher GID in an rclpy ``MessageInfo`` (None when absent)."""
    if not isinstance(info, dict):
        return None
    gid = info.get("publisher_gid")
    if not isinstance(gid, dict) or gid.get("data") is None:
        return None
    return bytes(gid["data"])


def gid_text(gid: bytes) -> str:
    """A GID as people read it in ``ros2 topic info -v``: hex bytes joined by dots."""
    return ".".join(f"{b:02x}" for b in gid)


@dataclass
class InputGuard:
    """The sender check of one input topic. ``active``: the simulator belongs to a launched flight."""

    active: bool
    flight_nodes: tuple[str, ...] = FLIGHT_NODES
    topic: str = "/lander/throttle"
    verbs: bool = True  #: the lander verbs' nodes (``/lander_*``) are taken too
    #: node name -> GID of the publisher owning it (the first heard in the flight)
    owners: dict[str, bytes] = field(default_factory=dict)
    #: GID -> its verdict once the graph named it: None taken, else the node name of the stranger
    verdicts: dict[bytes, str | None] = field(default_factory=dict)

    def refusal(self, info: Any, graph: Callable[[], Iterable[Any]]) -> str | None:
        """None when the message of ``info`` is taken; else why it is refused: a sentence naming
        the stranger for its first message, ``""`` for its later ones (counted, not announced).

        ``graph()``: the topic's publishers as ``rclpy`` ``TopicEndpointInfo`` (``node_name``,
        ``node_namespace``, ``endpoint_gid``), asked only for a GID not seen before."""
        if not self.active:
            return None
        gid = gid_of(info)
        if gid is None:
            return None  # no sender given (an rmw without GIDs): nothing to judge by
        if gid in self.verdicts:
            stranger = self.verdicts[gid]
            return None if stranger is None else ""
        # rmw_fastrtps lists an endpoint as soon as DDS discovered it, under a placeholder name until
        # its participant's node information has come too: not named yet.
        names = {bytes(e.endpoint_gid): _full_name(e.node_namespace, e.node_name) for e in graph()
                 if UNKNOWN_NODE not in e.node_name}
        node = names.get(gid)
        if node is None:
            # Not in the graph yet (module docstring): before the flight's own publisher is known it
            # may be that one, and is taken; after, it is a newcomer, refused (counted, not
            # announced) until the graph names it.
            return "" if self.owners else None
        stranger = self._judge(gid, node, names)
        self.verdicts[gid] = stranger
        if stranger is None:
            return None
        return (f"{self.topic} from {node} (publisher {gid_text(gid)}) refused: not of this flight "
                f"({self._why(node)}); its messages are counted as {STRANGER_KIND}")

    def _judge(self, gid: bytes, node: str, names: dict[bytes, str]) -> str | None:
        if node in self.flight_nodes:
            owner = self.owners.get(node)
            if owner is None or owner == gid or owner not in names:
                self.owners[node] = gid  # the first heard, or the owner left the graph
                return None
            return node
        if self.verbs and node.startswith(VERB_PREFIX) and node not in FLIGHT_NODES:
            return None
        return node

    def _why(self, node: str) -> str:
        if node in self.flight_nodes:
            return f"this flight's {node} is another publisher: a second flight runs in this ROS domain"
        verbs = f" and the lander verbs ({VERB_PREFIX}*)" if self.verbs else ""
        return f"only {', '.join(self.flight_nodes)}{verbs} publish it in this flight"


def _full_name(namespace: str, name: str) -> str:
    return namespace.rstrip("/") + "/" + name




def with_message_info(callback: Callable[[Any, Any], None]) -> Callable[..., None]:
    """``callback(msg, info)`` as a subscription callback that rclpy hands the ``MessageInfo``.

    rclpy tells the kinds apart by the callback's signature (two parameters: with the info). Its
    standard executors call ``cb(msg, info)``; its EventsExecutor (the simulator's) calls
    ``cb((msg, info))`` with one tuple (rclpy's events_executor.cpp, HandleSubscriptionReady), so
    the wrapper takes either form."""

    def run(*args: Any) -> None:
        if len(args) == 1 and isinstance(args[0], tuple):
            args = args[0]
        callback(args[0], args[1] if len(args) > 1 else None)

    p = inspect.Parameter
    run.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [p("msg", p.POSITIONAL_ONLY), p("info", p.POSITIONAL_ONLY)])
    return run
