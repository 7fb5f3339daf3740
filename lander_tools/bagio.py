"""Reading and writing rosbag2 bags of lander flights (no rclpy needed).

Reading: :func:`read_bag` opens any rosbag2 bag (MCAP or sqlite3) with the
``rosbags`` reader, registering the message types from the definitions the bag
itself carries, and turns every topic into numpy time series
(:meth:`Bag.series`). A truncated or damaged MCAP file (e.g. a recorder killed
with SIGKILL, so no index and no ``metadata.yaml``) is read record by record up
to the damage, with a warning; anything unreadable raises :class:`BagError`
whose message names the file and what is wrong.

Writing: :func:`lander_typestore` is the ``rosbags`` type store with the
project's custom messages (``lander_interfaces/msg/*.msg``) registered, which a
``rosbags`` Writer needs to embed their definitions in a bag; :func:`message_class` is the
rclpy class of a type name, which a subscription needs (it imports the type's package only).

Time: messages with a ``header`` are placed at their ``header.stamp``
(simulation time). Header-less messages (``std_msgs/Float64`` demand altitude,
``/clock`` itself) are placed at the simulation time the recorder had seen when
it received them, mapped through the recorded ``/clock`` (bag time -> sim time).
"""
from __future__ import annotations

import importlib
import os
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lander_ros.stamps import stamp_to_seconds

#: Storage formats a bag can be written in (``--storage``).
STORAGES = ("mcap", "sqlite3")


class BagError(ValueError):
    """A bag that cannot be read (missing, not a rosbag2 bag, damaged beyond use)."""


class BagWarning(UserWarning):
    """A bag that could be read only in part (truncated or without index)."""


# --- types ------------------------------------------------------------------------------------


def _msg_search_dirs() -> list[Path]:
    """Folders whose ``<pkg>/msg/<Name>.msg`` may hold a custom message definition.

    The source tree first (so a bag records what the code in this checkout sends),
    then the installed ``share/`` folders of AMENT_PREFIX_PATH and the interpreter.
    """
    dirs = [Path(__file__).resolve().parents[1]]
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    dirs += [Path(p) / "share" for p in prefixes]
    return dirs


def _find_msg_file(msgtype: str) -> Path | None:
    pkg, kind, name = msgtype.split("/")
    for d in _msg_search_dirs():
        candidate = d / pkg / kind / f"{name}.msg"
        if candidate.is_file():
            return candidate
    return None


def message_class(msgtype: str) -> Any:
    """The rclpy class of ``pkg/msg/Name`` (or ``pkg/srv/Name``): ``ImportError`` for a package
    that is not installed, ``AttributeError`` for a name the package lacks."""
    pkg, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def register_msgtype(typestore: Any, msgtype: str) -> None:
    """Register ``msgtype`` (``pkg/msg/Name``) and the custom types it uses in ``typestore``.

    Standard types come with the store; custom ones are parsed from their ``.msg``
    file. Raises :class:`BagError` naming the type when no definition is found.
    """
    from rosbags.typesys import get_types_from_msg

    pending = [msgtype]
    while pending:
        name = pending.pop()
        if name in typestore.fielddefs:
            continue
        path = _find_msg_file(name)
        if path is None:
            raise BagError(
                f"no definition for message type {name!r}: looked for "
                f"{name.split('/')[0]}/msg/{name.split('/')[-1]}.msg in "
                + ", ".join(str(d) for d in _msg_search_dirs())
            )
        types = get_types_from_msg(path.read_text(), name)
        # Nested custom types must be registered first; collect the ones the store lacks.
        missing = set()
        for _, (_, fields) in types.items():
            for _, ftype in fields:
                missing |= _referenced_types(ftype)
        missing = {m for m in missing if m not in typestore.fielddefs and m != name}
        if missing:
            pending.append(name)
            pending.extend(sorted(missing))
            continue
        typestore.register(types)


def _referenced_types(ftype: Any) -> set[str]:
    """Message type names referenced by a rosbags field description."""
    from rosbags.interfaces import Nodetype

    kind, detail = ftype
    if kind == Nodetype.NAME:
        return {detail}
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return _referenced_types(detail[0])
    return set()


def lander_typestore() -> Any:
    """A ROS 2 Kilted type store with every ``lander_interfaces`` message registered."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    for d in _msg_search_dirs():
        folder = d / "lander_interfaces" / "msg"
        if folder.is_dir():
            for f in sorted(folder.glob("*.msg")):
                register_msgtype(store, f"lander_interfaces/msg/{f.stem}")
            break
    return store


# --- reading ----------------------------------------------------------------------------------


@dataclass
class Topic:
    """All messages of one topic: type, receive times (bag clock, ns) and decoded messages."""

    name: str
    msgtype: str
    t_bag_ns: np.ndarray
    messages: list[Any]

    @property
    def count(self) -> int:
        return len(self.messages)


@dataclass
class Bag:
    """A bag read into memory. ``warnings`` lists what could not be read (partial read)."""

    path: Path
    storage: str
    topics: dict[str, Topic]
    warnings: list[str] = field(default_factory=list)
    #: ``custom_data`` of the bag's metadata (the recorder stores scene, controller, ...).
    meta: dict[str, str] = field(default_factory=dict)
    _clock: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def __contains__(self, topic: str) -> bool:
        return topic in self.topics and self.topics[topic].count > 0

    def counts(self) -> dict[str, int]:
        """Messages per topic."""
        return {name: t.count for name, t in sorted(self.topics.items())}

    def messages(self, topic: str) -> list[Any]:
        """Decoded messages of ``topic`` in receive order; ``[]`` when the bag has none."""
        t = self.topics.get(topic)
        return [] if t is None else t.messages

    def sim_time_of(self, t_bag_ns: np.ndarray) -> np.ndarray:
        """Simulation time [s] the recorder had seen at bag times ``t_bag_ns``, from ``/clock``.

        Without a recorded ``/clock`` the bag time relative to the first message is returned.
        """
        if self._clock is None:
            clock = self.topics.get("/clock")
            if clock is not None and clock.count:
                sim = np.array([stamp_to_seconds(m.clock) for m in clock.messages])
                self._clock = (clock.t_bag_ns.astype(float), sim)
            else:
                t0 = min((float(t.t_bag_ns[0]) for t in self.topics.values() if t.count), default=0.0)
                self._clock = (np.array([t0, t0 + 1e9]), np.array([0.0, 1.0]))
        tb, sim = self._clock
        return _extrapolating_interp(np.asarray(t_bag_ns, dtype=float), tb, sim)

    def series(self, topic: str) -> dict[str, np.ndarray]:
        """Time series of every field of ``topic``, as numpy arrays keyed by field path.

        ``"t"`` is the simulation time [s] (``header.stamp`` when the type has one);
        nested fields are joined with dots (``"position.x"``); fixed-size numeric arrays
        become 2-D columns (``"euler_zxz"`` of shape (N, 3)); variable-length arrays are
        padded with NaN to the longest. Raises :class:`BagError` for a topic not in the bag.
        """
        t = self.topics.get(topic)
        if t is None:
            raise BagError(
                f"{self.path}: no topic {topic!r}; the bag has: {', '.join(sorted(self.topics)) or 'no topics'}"
            )
        cols: dict[str, list[Any]] = {}
        for m in t.messages:
            _flatten(m, "", cols)
        out = {k: _stack(v) for k, v in cols.items()}
        if "header.stamp.sec" in out:
            out["t"] = out["header.stamp.sec"] + 1e-9 * out["header.stamp.nanosec"]
        elif topic == "/clock" and "clock.sec" in out:
            out["t"] = out["clock.sec"] + 1e-9 * out["clock.nanosec"]
        else:
            out["t"] = self.sim_time_of(t.t_bag_ns) if t.count else np.zeros(0)
        return out


def _extrapolating_interp(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    # Clock messages arrive in order; holding the last known time beyond the ends is the
    # best estimate of "what the recorder had seen".
    order = np.argsort(xp, kind="stable")
    out: np.ndarray = np.interp(x, xp[order], fp[order])
    return out


def _flatten(msg: Any, prefix: str, cols: dict[str, list[Any]]) -> None:
    fields = getattr(msg, "__dataclass_fields__", None)
    if fields is None:
        cols.setdefault(prefix[:-1], []).append(msg)
        return
    for name in fields:
        if name == "__msgtype__":
            continue
        value = getattr(msg, name)
        if hasattr(value, "__dataclass_fields__"):
            _flatten(value, f"{prefix}{name}.", cols)
        else:
            cols.setdefault(prefix + name, []).append(value)


def _stack(values: list[Any]) -> np.ndarray:
    first = values[0] if values else None
    if isinstance(first, np.ndarray):
        n = max((len(v) for v in values), default=0)
        if all(len(v) == n for v in values):
            return np.array(values, dtype=float).reshape(len(values), n)
        out = np.full((len(values), n), np.nan)
        for i, v in enumerate(values):
            out[i, : len(v)] = v
        return out
    if isinstance(first, (bool, int, float, np.number, np.bool_)):
        return np.asarray(values)
    return np.asarray(values, dtype=object)


def read_bag(path: str | os.PathLike[str], topics: list[str] | None = None) -> Bag:
    """Read a rosbag2 bag (a bag folder, or a single ``.mcap``/``.db3`` file) into memory.

    Types are registered from the definitions embedded in the bag. If the bag is
    damaged (no ``metadata.yaml``, truncated MCAP) the readable part is returned and
    :class:`BagWarning` is issued (also listed in ``Bag.warnings``).

    Raises
    ------
    BagError
        The path is missing or nothing in it can be read as a rosbag2 bag.
    """
    p = Path(path)
    if not p.exists():
        raise BagError(f"bag not found: {p}")
    folder = p if p.is_dir() else p.parent
    if p.is_dir() and (p / "metadata.yaml").is_file():
        try:
            return _read_indexed(p, topics)
        except BagError:
            raise
        except Exception as err:  # noqa: BLE001 - rosbags raises many kinds; we fall back below
            first_error = f"{type(err).__name__}: {' '.join(str(err).split())}"  # one line: YAML errors span several
    else:
        first_error = "no metadata.yaml" if p.is_dir() else "a single file, not a bag folder"
    mcaps = [p] if p.is_file() and p.suffix == ".mcap" else sorted(folder.glob("*.mcap")) if p.is_dir() else []
    if not mcaps:
        raise BagError(f"{p}: not a readable rosbag2 bag ({first_error}; no .mcap file to recover from)")
    return _read_mcap_stream(mcaps[0], topics, first_error)


def _read_indexed(p: Path, topics: list[str] | None) -> Bag:
    from rosbags.highlevel import AnyReader

    with AnyReader([p]) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        storage = "mcap" if any(p.glob("*.mcap")) else "sqlite3"
        meta = _custom_data(p)
        data: dict[str, tuple[str, list[int], list[Any]]] = {
            c.topic: (c.msgtype, [], []) for c in conns
        }
        problems: list[str] = []
        try:
            for conn, ts, raw in reader.messages(connections=conns):
                entry = data[conn.topic]
                entry[1].append(ts)
                entry[2].append(reader.deserialize(raw, conn.msgtype))
        except Exception as err:  # noqa: BLE001
            problems.append(f"{p}: stopped reading at a damaged record ({type(err).__name__}: {err})")
    bag = Bag(
        p,
        storage,
        {k: Topic(k, v[0], np.array(v[1], dtype=np.int64), v[2]) for k, v in data.items()},
        problems,
        meta,
    )
    for w in problems:
        warnings.warn(w, BagWarning, stacklevel=3)
    return bag


def _custom_data(p: Path) -> dict[str, str]:
    """``custom_data`` of a bag's ``metadata.yaml`` (empty when absent or unreadable)."""
    import yaml

    try:
        info = yaml.safe_load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}
    except (OSError, KeyError, TypeError, yaml.YAMLError):
        return {}


def _read_mcap_stream(path: Path, topics: list[str] | None, why: str) -> Bag:
    """Recover what can be read from an MCAP file without its index, record by record."""
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    data: dict[str, tuple[str, list[int], list[Any]]] = {}
    problems = [f"{path}: read without index ({why})"]
    n = 0
    try:
        with path.open("rb") as f:
            for rec in StreamReader(f, record_size_limit=1 << 30).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                    if rec.encoding == "ros2msg" and rec.name not in store.fielddefs:
                        store.register(get_types_from_msg(rec.data.decode(), rec.name))
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message):
                    ch = channels.get(rec.channel_id)
                    if ch is None or (topics is not None and ch.topic not in topics):
                        continue
                    msgtype = schemas[ch.schema_id].name
                    entry = data.setdefault(ch.topic, (msgtype, [], []))
                    entry[2].append(store.deserialize_cdr(rec.data, msgtype))
                    entry[1].append(rec.log_time)
                    n += 1
    except Exception as err:  # noqa: BLE001 - the damage can show as any decoding error
        problems.append(f"{path}: truncated or damaged after {n} messages ({type(err).__name__}: {err})")
    if n == 0 and not channels:
        raise BagError(f"{path}: not a readable MCAP bag ({'; '.join(problems)})")
    for w in problems:
        warnings.warn(w, BagWarning, stacklevel=3)
    return Bag(
        path,
        "mcap",
        {k: Topic(k, v[0], np.array(v[1], dtype=np.int64), v[2]) for k, v in data.items()},
        problems,
    )


