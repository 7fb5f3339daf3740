"""Where a flight runs on the middleware: its ROS domain and discovery range, chosen so that flights
on one machine never meet, and the per-user run file through which the ``lander`` verbs find the
user's own flight (docs/flying.md, "Flights kept apart"). Plain Python: no ROS here.

ROS 2 keeps participants apart by two settings, read by every process from its environment:

* ``ROS_DOMAIN_ID`` (0-101 on Linux: Fast DDS maps domain d to UDP ports 7400 + 250 d, and above
  101 they fall into Linux's ephemeral port range): participants of different domains never
  discover each other. A flight takes the user's ``ROS_DOMAIN_ID`` or ``--domain``; without either
  it takes a domain no other flight or test run on this machine holds (:func:`claim_free_domain`:
  an advisory lock per domain, dropped by the kernel when the launcher exits). A domain the user
  chose is held the same way (:func:`hold_domain`), so a second flight there is refused at once.
* ``ROS_AUTOMATIC_DISCOVERY_RANGE``: ``LOCALHOST`` keeps discovery and traffic on this machine,
  ``SUBNET`` (ROS's default) reaches the local network. A flight and the verbs use ``LOCALHOST``
  unless the user set the variable or asked for the network (``--network``: ``SUBNET``).

The domain changes no message of the flight: a flight's bag is the same in any domain.
"""
from __future__ import annotations

import fcntl
import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

#: The domains a flight may pick (0 is every unconfigured ROS process's: never picked).
DOMAIN_MIN, DOMAIN_MAX = 1, 101
LOCALHOST, SUBNET = "LOCALHOST", "SUBNET"
DOMAIN_VAR, RANGE_VAR = "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"
#: Machine-wide lock files of the domains flights hold (one per domain; any user may create one).
LOCK_DIR = Path(tempfile.gettempdir()) / "mars_lander_domains"
#: The test suite's own domain locks (test/rosutil.py): a flight never picks a domain a test run holds.
TEST_LOCK_DIR = Path(tempfile.gettempdir()) / "mars_lander_test_domains"


@dataclass(frozen=True)
class FlightPlace:
    """A flight's domain and discovery range, and how each was chosen (for the first line)."""

    domain: int
    discovery: str
    domain_from: str  #: "picked free on this machine", "ROS_DOMAIN_ID", "--domain"
    discovery_from: str  #: "default", "ROS_AUTOMATIC_DISCOVERY_RANGE", "--network"

    def env(self) -> dict[str, str]:
        return {DOMAIN_VAR: str(self.domain), RANGE_VAR: self.discovery}

    def describe(self) -> str:
        """``ROS_DOMAIN_ID=7 (picked free on this machine), discovery LOCALHOST (default)``."""
        return (f"{DOMAIN_VAR}={self.domain} ({self.domain_from}), discovery {self.discovery} "
                f"({self.discovery_from})")


class DomainLock:
    """A held domain: the lock file stays locked until :meth:`release` or the process's end."""

    def __init__(self, domain: int, handle: IO[str] | None) -> None:
        self.domain, self._handle = domain, handle

    def release(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None


def _try_lock(path: Path, exclusive: bool) -> IO[str] | None:
    """The open, locked file ``path`` (created if missing), or None when another process holds it."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CREAT, 0o666)
    except OSError:
        return None
    handle = os.fdopen(fd, "r")
    try:
        fcntl.flock(handle, (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        return None
    return handle


def _held_by_tests(domain: int) -> bool:
    path = TEST_LOCK_DIR / f"{domain}.lock"
    if not path.exists():
        return False
    probe = _try_lock(path, exclusive=False)
    if probe is None:
        return True
    probe.close()
    return False


def _make_lock_dir() -> None:
    """LOCK_DIR, shared by every user's flights (sticky, writable by all)."""
    try:
        LOCK_DIR.mkdir(mode=0o1777, exist_ok=True)
        LOCK_DIR.chmod(0o1777)  # any user's flights share it (mkdir's mode is cut by the umask)
    except OSError:
        pass  # another user's folder: its mode is theirs to set, its files are shared all the same


def claim_free_domain(start: int | None = None) -> DomainLock:
    """Hold a domain in DOMAIN_MIN..DOMAIN_MAX that no flight or test run on this machine holds,
    walking up from one derived from ``start`` (default: this pid); ValueError when all are taken."""
    _make_lock_dir()
    span = DOMAIN_MAX - DOMAIN_MIN + 1
    first = (os.getpid() if start is None else start) % span
    for k in range(span):
        domain = DOMAIN_MIN + (first + k) % span
        if _held_by_tests(domain):
            continue
        handle = _try_lock(LOCK_DIR / f"{domain}.lock", exclusive=True)
        if handle is not None:
            return DomainLock(domain, handle)
    raise ValueError(f"every ROS domain {DOMAIN_MIN}-{DOMAIN_MAX} is held by another flight on this machine; "
                     f"set {DOMAIN_VAR} to share one (lander fly then refuses to join a running flight)")


class DomainTaken(ValueError):
    """Another flight runs in the flight's ROS domain: the flight is refused before it starts."""

    def __init__(self, domain: int | str, what: str) -> None:
        super().__init__(f"another flight is running in {DOMAIN_VAR}={domain} ({what}): refused, nothing flown or "
                         f"recorded; unset {DOMAIN_VAR} (lander fly then picks a free domain) or choose another")


def hold_domain(domain: int) -> DomainLock:
    """Hold ``domain``, one the user chose, for one flight; :class:`DomainTaken` when another
    ``lander fly`` on this machine holds it. The lock sees flights on this machine at once, before
    any discovery; flights elsewhere on the network (or not started by ``lander fly``) are found in
    the ROS graph at start-up (:func:`lander_tools.fly.flight.strangers_in_graph`)."""
    _make_lock_dir()
    handle = _try_lock(LOCK_DIR / f"{domain}.lock", exclusive=True)
    if handle is None and (LOCK_DIR / f"{domain}.lock").exists():
        raise DomainTaken(domain, "another lander fly on this machine holds it")
    return DomainLock(domain, handle)  # an unreadable lock folder: the graph check still refuses


def choose_place(environ: dict[str, str] | Any, domain: int | None = None,
                 network: bool = False) -> tuple[FlightPlace, DomainLock]:
    """The flight's place and its held lock (release it when the flight is over): ``domain``
    (``--domain``), else the user's ``ROS_DOMAIN_ID`` (:func:`hold_domain`: refused when another
    ``lander fly`` here holds it), else a free one; discovery ``SUBNET`` with ``network``, else the
    user's ``ROS_AUTOMATIC_DISCOVERY_RANGE``, else ``LOCALHOST``."""
    if domain is not None:
        chosen, domain_from = domain, "--domain"
    elif environ.get(DOMAIN_VAR, "").strip():
        chosen, domain_from = parse_domain(environ[DOMAIN_VAR], DOMAIN_VAR), DOMAIN_VAR
    if domain is not None or environ.get(DOMAIN_VAR, "").strip():
        lock = hold_domain(chosen)
    else:
        lock = claim_free_domain()
        chosen, domain_from = lock.domain, "picked free on this machine"
    if network:
        discovery, discovery_from = SUBNET, "--network"
    elif environ.get(RANGE_VAR, "").strip():
        discovery, discovery_from = environ[RANGE_VAR].strip(), RANGE_VAR
    else:
        discovery, discovery_from = LOCALHOST, "this machine only; --network for the network"
    return FlightPlace(chosen, discovery, domain_from, discovery_from), lock


def parse_domain(text: str, what: str) -> int:
    """A domain id from ``text``; ValueError naming ``what`` unless it is an integer 0-232."""
    try:
        value = int(str(text).strip())
    except ValueError:
        raise ValueError(f"{what} = {text!r}: must be an integer ROS domain id (0-101)") from None
    if not 0 <= value <= 232:  # 232: the last domain whose Fast DDS ports fit in 16 bits
        raise ValueError(f"{what} = {value}: must be a ROS domain id 0-101 (0-232 where the ports allow)")
    return value


# --- the run file ---------------------------------------------------------------------------------


def run_dir() -> Path:
    """This user's run-file folder: ``$XDG_RUNTIME_DIR/mars-lander``, else ``/tmp/mars-lander-UID``."""
    base = os.environ.get("XDG_RUNTIME_DIR")
    return Path(base) / "mars-lander" if base else Path(tempfile.gettempdir()) / f"mars-lander-{os.getuid()}"


@dataclass(frozen=True)
class RunningFlight:
    """One line of the run file: a flight this user's ``lander fly`` is flying now."""

    pid: int
    domain: int
    discovery: str
    scene: str
    started: float  #: wall clock [s since the epoch]


def write_run_file(place: FlightPlace, scene: str) -> Path:
    """Announce this process's flight to the user's verbs; returns the file (remove it at the end)."""
    folder = run_dir()
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    path = folder / f"flight-{os.getpid()}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"pid": os.getpid(), "domain": place.domain, "discovery": place.discovery,
                               "scene": scene, "started": time.time()}))
    tmp.replace(path)
    return path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def running_flights() -> list[RunningFlight]:
    """This user's flights running now, oldest first (files of launchers that died are removed)."""
    out = []
    folder = run_dir()
    for path in sorted(folder.glob("flight-*.json")) if folder.is_dir() else []:
        try:
            d = json.loads(path.read_text())
            flight = RunningFlight(int(d["pid"]), int(d["domain"]), str(d["discovery"]), str(d["scene"]),
                                   float(d["started"]))
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if _alive(flight.pid):
            out.append(flight)
        else:
            path.unlink(missing_ok=True)
    return sorted(out, key=lambda f: f.started)


@dataclass(frozen=True)
class Attachment:
    """What :func:`attach_env` found: the user's flight in the domain the verb now uses (None: no
    run file says one runs there) and a line to show when the choice needs saying."""

    flight: RunningFlight | None
    note: str | None = None


def attach_env(environ: Any = None) -> Attachment:
    """Set ``environ`` (default os.environ) for a verb before it starts ROS: the user's own
    ``ROS_DOMAIN_ID`` is kept; else the newest of the user's running flights' domain and discovery
    range; discovery ``LOCALHOST`` unless the user set it."""
    environ = os.environ if environ is None else environ
    note = None
    flights = running_flights()
    mine: RunningFlight | None = None
    if environ.get(DOMAIN_VAR, "").strip():
        mine = next((f for f in reversed(flights) if str(f.domain) == environ[DOMAIN_VAR].strip()), None)
    elif flights:
        mine = flights[-1]
        environ[DOMAIN_VAR] = str(mine.domain)
        if not environ.get(RANGE_VAR, "").strip():
            environ[RANGE_VAR] = mine.discovery
        if len(flights) > 1:
            others = ", ".join(f"{f.scene!r} in {f.domain}" for f in flights[:-1])
            note = (f"{len(flights)} of your flights are running: this talks to the newest, {mine.scene!r} in "
                    f"{DOMAIN_VAR}={mine.domain} (others: {others}; set {DOMAIN_VAR} to choose)")
    if not environ.get(RANGE_VAR, "").strip():
        environ[RANGE_VAR] = LOCALHOST
    return Attachment(mine, note)
