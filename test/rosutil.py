"""Helpers for tests that use ROS 2: middleware isolation, waiting on conditions, child processes.

Pure helpers (no fixtures; test/conftest.py wraps them). Importable from any test as
``import rosutil`` because pytest puts test/ on sys.path for the root conftest.
"""

from __future__ import annotations

import atexit
import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

# Fast DDS maps a domain id to UDP ports 7400 + 250 * id; above 101 they collide with Linux's
# ephemeral port range. 0 is what an unconfigured ROS process uses: tests never share it.
DOMAIN_MIN, DOMAIN_MAX = 1, 101

#: Test files (paths under test/, folders end in "/") that start ROS participants, in the test
#: process or in child processes. A new ROS test file belongs here.
ROS_TESTS = ("autopilot_node/", "flights/", "interfaces/", "live/", "reliability/", "sim_node/",
             "sweep/test_through_ros.py", "tools/test_analyse_command.py", "tools/test_deorbit_params_example.py",
             "tools/test_estimate_flight.py", "tools/test_flights_apart.py", "tools/test_headline_flight.py",
             "tools/test_launch_file.py", "tools/test_record_command.py", "test_cli.py")

#: The ROS test files that keep Fast DDS's default transports (shared memory beside UDP), as a
#: user's flight does. Under pytest-xdist (``--dist loadgroup``; conftest sets the groups) they run
#: in one worker, one after the other: Fast DDS allocates shared-memory ports machine-wide
#: (``fastdds_port7000`` up, whatever the domain), and when two workers start participants at once
#: on a loaded machine, a participant's wait for a port's mutex times out and it breaks the mutex
#: (eProsima/Fast-DDS#6117). Seen in two workers: "Failed init_port fastdds_port7001:
#: open_and_lock_file failed" printed into a verb's one-line answer, and a flight whose nodes never
#: met. The other ROS files run file by file in any worker over loopback UDP alone
#: (:data:`LOOPBACK_UDP`, set for their whole module), which opens no shared-memory port.
ROS_SHM_TESTS = ("reliability/", "flights/test_new_user.py", "tools/test_flights_apart.py", "test_cli.py",
                 "interfaces/test_isolation.py")

#: The Fast DDS profile of :data:`LOOPBACK_UDP`: rmw_fastrtps's localhost discovery less its
#: shared-memory transport (unicast discovery to 127.0.0.1, sockets on loopback only, UDPv4 alone).
LOOPBACK_PROFILE = Path(__file__).resolve().parent / "fastdds_udp_loopback.xml"

#: Environment of a ROS test file outside :data:`ROS_SHM_TESTS` (read by every participant at its
#: creation; children inherit it). ``LOCALHOST`` cannot be kept: for it rmw_fastrtps builds the
#: participant's transports itself, always with shared memory, whatever ``FASTDDS_BUILTIN_TRANSPORTS``
#: or a profile says; ``SYSTEM_DEFAULT`` leaves the participant to the default profile, which keeps
#: discovery and traffic on this machine as ``LOCALHOST`` does.
LOOPBACK_UDP = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT",
                "FASTDDS_DEFAULT_PROFILES_FILE": str(LOOPBACK_PROFILE)}


def xdist_group(rel: str) -> str:
    """The pytest-xdist group of the test file ``rel`` (its path under test/): ``ros`` for the
    files that share the shared-memory transport, else the file itself (any worker takes it)."""
    return "ros" if rel.startswith(ROS_SHM_TESTS) else rel


def transports_env(rel: str) -> dict[str, str]:
    """Environment variables the test file ``rel`` runs under, over the suite's (see :data:`ROS_SHM_TESTS`)."""
    return LOOPBACK_UDP if rel.startswith(ROS_TESTS) and not rel.startswith(ROS_SHM_TESTS) else {}


_LOCK_DIR = Path(tempfile.gettempdir()) / "mars_lander_test_domains"
#: The domains ``lander fly`` holds for its flights (lander_tools.fly.domain.LOCK_DIR): a test
#: never claims one a user's flight on this machine flies in.
_FLIGHT_LOCK_DIR = Path(tempfile.gettempdir()) / "mars_lander_domains"
_held_locks: dict[int, Any] = {}  # domain -> its open lock file (held until released or exit)


def _flight_holds(domain: int) -> bool:
    """A ``lander fly`` flight holds ``domain`` now (its lock file is locked; no file: none)."""
    try:
        f = open(_FLIGHT_LOCK_DIR / f"{domain}.lock")
    except OSError:
        return False
    with f:
        try:
            fcntl.flock(f, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            return True
        return False


def claim_domain_id(seed: int | None = None) -> int:
    """A ROS_DOMAIN_ID in 1..101 that no other live test run on this machine holds and no user's
    ``lander fly`` flight flies in.

    Starts from one derived from ``seed`` (default: this pid) and walks up until it can take an
    exclusive lock on ``/tmp/mars_lander_test_domains/<id>.lock`` (which ``lander fly`` never
    picks) of a domain whose flight lock (``/tmp/mars_lander_domains/<id>.lock``) nobody holds;
    the locks die with their processes, so a crashed run frees its id.
    """
    _LOCK_DIR.mkdir(parents=True, exist_ok=True)
    span = DOMAIN_MAX - DOMAIN_MIN + 1
    start = (os.getpid() if seed is None else seed) % span
    for k in range(span):
        domain = DOMAIN_MIN + (start + k) % span
        f = open(_LOCK_DIR / f"{domain}.lock", "w")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        if _flight_holds(domain):
            f.close()
            continue
        _held_locks[domain] = f
        return domain
    raise RuntimeError(f"all ROS domain ids {DOMAIN_MIN}..{DOMAIN_MAX} are taken by other test runs")


def release_domain_id(domain: int) -> None:
    """Give back a domain id taken by :func:`claim_domain_id` (no-op if not held)."""
    f = _held_locks.pop(domain, None)
    if f is not None:
        f.close()


@atexit.register
def _release_all() -> None:
    # A run's own domain is held to its end; closed here rather than by the interpreter's teardown,
    # which warned of each open lock file (ResourceWarning) after every run.
    for domain in list(_held_locks):
        release_domain_id(domain)


#: Set in this process's environment (so inherited by everything it starts): which test run a
#: process belongs to, so one run never reaps another run's processes in a reused domain id.
RUN_MARKER = "MARS_LANDER_TEST_RUN"
os.environ.setdefault(RUN_MARKER, str(os.getpid()))


def processes_in_domain(domain: int) -> list[Any]:
    """Live processes of this user and this test run, other than this one, whose environment has
    ROS_DOMAIN_ID=domain (psutil.Process objects): the nodes and tools a test started there. multiprocessing's own
    helpers (resource tracker, fork server), which live as long as this process, are not counted."""
    import psutil

    me = os.getpid()
    found = []
    for p in psutil.process_iter(["pid", "uids"]):
        if p.pid == me or p.info["uids"] is None or p.info["uids"].real != os.getuid():
            continue
        try:
            if any("multiprocessing." in part for part in p.cmdline()[:4]):
                continue
            env = p.environ()
            if (env.get("ROS_DOMAIN_ID") == str(domain) and env.get(RUN_MARKER) == os.environ[RUN_MARKER]
                    and p.status() != psutil.STATUS_ZOMBIE):
                found.append(p)
        except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
            continue
    return found


def reap_domain(domain: int, grace: float = 5.0) -> list[str]:
    """Wait up to ``grace`` s for the processes left in ``domain`` to exit, then kill them.

    Returns a description of each one that had to be killed (empty: nothing leaked).
    """
    import psutil

    left = processes_in_domain(domain)
    if not left:
        return []
    _, alive = psutil.wait_procs(left, timeout=grace)
    killed = []
    for p in alive:
        try:
            killed.append(f"pid {p.pid}: {' '.join(p.cmdline())[:200]}")
            p.kill()
        except psutil.NoSuchProcess:
            pass
    psutil.wait_procs(alive, timeout=grace)
    return killed


def isolate_middleware(env: dict[str, str] | None = None, domain_id: int | None = None) -> int:
    """Set (in ``env``, default os.environ) a private domain id and localhost-only discovery."""
    env = os.environ if env is None else env
    domain = claim_domain_id() if domain_id is None else domain_id
    env["ROS_DOMAIN_ID"] = str(domain)
    # Kilted ignores ROS_LOCALHOST_ONLY; this keeps discovery and traffic on loopback.
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_LOCALHOST_ONLY", None)
    return domain


def clean_stale_fastdds_shm(shm_dir: str | Path = "/dev/shm", min_age_s: float = 2.0,
                            zombie_ports: bool = True) -> list[Path]:
    """Remove Fast DDS shared-memory files left by processes that died (e.g. SIGKILLed nodes).

    Each segment ``fastdds_<16 hex>`` and each port ``fastdds_port<N>`` has a lock file ``..._el``
    (exclusive user) or ``..._sl`` (shared listeners) that its live users hold with flock; if
    none of them is held, nobody alive uses it, so it goes with its lock files and the port mutex
    ``sem.<name>_mutex`` (the rule of ``fastdds shm clean``). Unlike that tool, a port whose lock
    file is missing altogether goes too: a process killed while creating a port leaves an empty,
    never-initialised file, and every later participant that picks that port number spins forever
    waiting for its initialisation (seen: the whole suite hung in ``Node()``). Files younger than
    ``min_age_s`` are left alone: their creator may not have locked them yet.

    ``zombie_ports=False`` leaves a port whose lock files exist but are not held: while other
    processes may be starting participants. Port numbers (``fastdds_port7000`` up) are shared by
    every domain, and a participant that picks a dead one re-initialises and reuses it (checked:
    a SIGKILLed node's port 7000 was taken over by the next participant, and gone when it exited);
    removing it meanwhile can pull the file from under that participant (another run's, or another
    pytest-xdist worker's). Segments are named per participant, so a dead one's is never reopened.
    """
    removed: list[Path] = []
    shm = Path(shm_dir)
    now = time.time()

    def held(lock: Path) -> bool:
        try:
            fd = os.open(lock, os.O_RDONLY)
        except OSError:
            return False  # no lock file: no live user
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return False
        except OSError:
            return True
        finally:
            os.close(fd)

    for base in shm.glob("fastdds_*"):
        if base.name.endswith(("_el", "_sl")):
            continue
        try:
            st = base.stat()
        except OSError:
            continue  # vanished meanwhile
        if now - st.st_mtime < min_age_s or st.st_uid != os.getuid():
            continue
        locks = [base.with_name(base.name + sfx) for sfx in ("_el", "_sl")]
        if not base.name.startswith("fastdds_port") and not any(lk.exists() for lk in locks):
            continue  # a segment is always created with its lock: leave unknown files alone
        if any(held(lk) for lk in locks):
            continue
        if not zombie_ports and base.name.startswith("fastdds_port") and any(lk.exists() for lk in locks):
            continue  # Fast DDS takes it over itself; see the docstring
        for f in (base, *locks, shm / f"sem.{base.name}_mutex"):
            try:
                f.unlink()
                removed.append(f)
            except FileNotFoundError:
                pass
    return removed


def wait_for(predicate: Callable[[], bool], timeout: float, executor: Any = None,
             what: str = "condition", poll: float = 0.02) -> None:
    """Spin ``executor`` (if given) until ``predicate()`` is true; TimeoutError after ``timeout`` s.

    Never a fixed sleep: returns as soon as the condition holds, so the timeout can be generous
    (discovery takes up to ~3 s with several processes starting on 2 cores).
    """
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what} not reached within {timeout} s")
        if executor is not None:
            executor.spin_once(timeout_sec=poll)
        else:
            time.sleep(poll)


class ChildProcess:
    """A Python child process (a node, a publisher, ...) with this process's environment.

    Output goes to a temporary log file (no pipe to fill up); ``stop()`` sends SIGINT, then
    SIGKILL if it has not exited within ``grace`` s. Use as a context manager or via the
    ``spawn_python`` fixture, which stops it at teardown.
    """

    def __init__(self, args: Sequence[str], env: dict[str, str] | None = None,
                 cwd: str | Path | None = None, name: str = "child") -> None:
        self.name = name
        self.log = tempfile.NamedTemporaryFile(prefix=f"{name}-", suffix=".log", delete=False)
        full_env = dict(os.environ if env is None else env)
        full_env.setdefault("PYTHONUNBUFFERED", "1")
        self.proc = subprocess.Popen([sys.executable, *args], stdout=self.log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, env=full_env, cwd=cwd)

    @property
    def returncode(self) -> int | None:
        return self.proc.poll()

    def output(self) -> str:
        self.log.flush()
        return Path(self.log.name).read_text(errors="replace")

    def stop(self, grace: float = 5.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(grace)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def close(self) -> None:
        self.stop()
        self.log.close()
        Path(self.log.name).unlink(missing_ok=True)

    def __enter__(self) -> ChildProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def param_value(v: object) -> Any:
    """``rcl_interfaces/ParameterValue`` of a Python value, typed by it, as the live bridge makes them
    (:func:`lander_tools.live.params.parameter_value`); but a list goes as it is into a double
    array, unconverted (an empty or mixed list too: the fuzz tests send those on purpose)."""
    from rcl_interfaces.msg import ParameterType, ParameterValue

    from lander_tools.live.params import parameter_value

    if isinstance(v, list):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=v)
    return parameter_value(v)


def sim_service_clients(node: Any) -> dict[str, Any]:
    """Clients of the simulator node's own services, by name (``load_scene``, ``reset``, ...)."""
    from std_srvs.srv import SetBool, Trigger

    from lander_interfaces.srv import LoadScene, Reset, RunUntil, StepSimulation

    types = {"load_scene": LoadScene, "reset": Reset, "pause": Trigger, "resume": Trigger,
             "step": StepSimulation, "run_until": RunUntil, "deploy_parachute": Trigger,
             "set_stabiliser": SetBool, "subscribers": Trigger}
    return {name: node.create_client(t, f"/lander/{name}") for name, t in types.items()}


# --- one way to start a node, one observer ------------------------------------------------------

REPO = Path(__file__).resolve().parent.parent


def ros_args(params: dict[str, object]) -> list[str]:
    """``--ros-args -p k:=v ...`` for a child node (booleans as true/false, an empty string as '')."""
    args = ["--ros-args"]
    for k, v in params.items():
        if isinstance(v, bool):
            lit = "true" if v else "false"
        elif isinstance(v, str):
            lit = v if v else "''"
        else:
            lit = repr(v)
        args += ["-p", f"{k}:={lit}"]
    return args


def start_node(module: str, params: dict[str, object] | None = None, name: str | None = None,
               env: dict[str, str] | None = None, params_file: str | Path | None = None) -> ChildProcess:
    """``python -m MODULE --ros-args [--params-file F] -p ...`` from the repository root (a node
    under test); the ``-p`` overrides come after the file, so they win."""
    args = ros_args(params or {})
    if params_file is not None:
        args[1:1] = ["--params-file", str(params_file)]
    return ChildProcess(["-m", module, *args], env=env, cwd=REPO, name=name or module.rsplit(".", 1)[-1])


class Observer:
    """A test-side rclpy node (no mock of ROS) that records topics, publishes and calls services.

    Every wait spins its executor until a condition holds, TimeoutError naming the condition after
    the timeout; nothing sleeps a fixed time. ``record`` subscribes a list to a topic; ``received``
    counts what the recorders took (``drain`` watches it); ``call`` waits for the service, then
    its answer. Subclasses (the suites' ground station, watch and probe) add their topics."""

    #: Generous: discovery and process start-up (rclpy + python-control imports) on a loaded 2-core machine.
    start_timeout = 45.0
    #: One request/answer over the middleware.
    reply_timeout = 15.0

    def __init__(self, name: str, context: Any = None, node_kwargs: dict[str, Any] | None = None) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.node = Node(name, context=context, **(node_kwargs or {}))
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.received = 0
        self.clients: dict[str, Any] = {}

    def record(self, topic: str, msg_type: Any, store: Any = None, depth: int = 10_000,
               qos: Any = None) -> Any:
        """Subscribe ``store`` (a new list by default) to ``topic``; returns it."""
        store = [] if store is None else store

        def keep(msg: Any) -> None:
            store.append(msg)
            self.received += 1

        self.node.create_subscription(msg_type, topic, keep, depth if qos is None else qos)
        return store

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    def wait_for(self, predicate: Callable[[], bool], timeout: float | None = None, what: str = "condition",
                 poll: float = 0.01) -> None:
        wait_for(predicate, self.reply_timeout if timeout is None else timeout, self.executor, what, poll=poll)

    def spin_for(self, seconds: float) -> None:
        """Serve callbacks for ``seconds`` of wall time (a measuring window, not a synchronisation)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.01, max(0.0, end - time.monotonic())))

    def drain(self, timeout: float | None = None) -> None:
        """Take every message already queued: spin until two spins in a row take none (call it
        once the publishers are quiet, e.g. the simulation paused, before reading records as complete)."""
        idle = 0

        def quiet() -> bool:
            nonlocal idle
            before = self.received
            self.executor.spin_once(timeout_sec=0.05)
            idle = idle + 1 if self.received == before else 0
            return idle >= 2

        wait_for(quiet, self.reply_timeout if timeout is None else timeout, None, "queued messages drained", poll=0.0)

    def wait_graph(self, subscribers: dict[str, int], publishers: dict[str, int] | None = None,
                   services: tuple[str, ...] = ()) -> None:
        """Until this node sees at least the given numbers of subscribers / publishers per topic and
        the named clients' services are ready."""
        n, pubs = self.node, publishers or {}

        def ready() -> bool:
            return (all(n.count_subscribers(t) >= k for t, k in subscribers.items())
                    and all(n.count_publishers(t) >= k for t, k in pubs.items())
                    and all(self.clients[s].service_is_ready() for s in services))

        try:
            self.wait_for(ready, self.start_timeout, f"discovery of {subscribers} / {pubs} / {services}")
        except TimeoutError as exc:  # say what the graph did show, so a slow discovery tells where it stood
            seen = ({t: n.count_subscribers(t) for t in subscribers}, {t: n.count_publishers(t) for t in pubs},
                    {s: self.clients[s].service_is_ready() for s in services})
            raise TimeoutError(f"{exc}; seen: subscribers {seen[0]}, publishers {seen[1]}, services {seen[2]}, "
                               f"nodes {sorted(n.get_node_names())}") from None

    def call(self, client: Any, request: Any = None, timeout: float | None = None) -> Any:
        """Call a service (a client, or the name of one in ``clients``) and return its answer."""
        if isinstance(client, str):
            client = self.clients[client]
        self.wait_for(client.service_is_ready, self.start_timeout, f"service {client.srv_name}")
        future = client.call_async(client.srv_type.Request() if request is None else request)
        self.wait_for(future.done, timeout, f"answer of {client.srv_name}")
        return future.result()

    def parameter(self, client: Any, name: str) -> Any:
        """Current value of a node's parameter ``name`` through its ``get_parameters`` service client."""
        from rcl_interfaces.msg import Parameter as ParameterMsg
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import Parameter

        reply = self.call(client, GetParameters.Request(names=[name]))
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=reply.values[0])).value
