"""Helpers for tests that use ROS 2: middleware isolation, waiting on conditions, child processes.

Pure helpers (no fixtures; test/conftest.py wraps them). Importable from any test as
``import rosutil`` because pytest puts test/ on sys.path for the root conftest.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Sequence

# Fast DDS maps a domain id to UDP ports 7400 + 250 * id; above 101 they collide with Linux's
# ephemeral port range. 0 is what an unconfigured ROS process uses: tests never share it.
DOMAIN_MIN, DOMAIN_MAX = 1, 101
_LOCK_DIR = Path(tempfile.gettempdir()) / "mars_lander_test_domains"
_held_locks: list[Any] = []  # keeps the claimed domain's lock file open for the process's life


def claim_domain_id(seed: int | None = None) -> int:
    """A ROS_DOMAIN_ID in 1..101 that no other live test run on this machine holds.

    Starts from one derived from ``seed`` (default: this pid) and walks up until it can take an
    exclusive lock on ``/tmp/mars_lander_test_domains/<id>.lock``; the lock dies with the process,
    so a crashed run frees its id.
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
        _held_locks.append(f)
        return domain
    raise RuntimeError(f"all ROS domain ids {DOMAIN_MIN}..{DOMAIN_MAX} are taken by other test runs")


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


def clean_stale_fastdds_shm(shm_dir: str | Path = "/dev/shm", min_age_s: float = 2.0) -> list[Path]:
    """Remove Fast DDS shared-memory files left by processes that died (e.g. SIGKILLed nodes).

    Each Fast DDS segment ``fastdds_X`` has a lock file ``fastdds_X_el`` that its live users hold
    with flock; if we can take an exclusive lock on it nobody alive uses it, so ``X``, ``X_el`` and
    the port mutex ``sem.X_mutex`` can go (the same rule as ``fastdds shm clean``). Files younger
    than ``min_age_s`` are left alone: their creator may not have locked them yet.
    """
    removed: list[Path] = []
    shm = Path(shm_dir)
    now = time.time()
    for el in shm.glob("fastdds_*_el"):
        base = el.with_name(el.name[: -len("_el")])
        try:
            if now - el.stat().st_mtime < min_age_s or el.stat().st_uid != os.getuid():
                continue
            fd = os.open(el, os.O_RDONLY)
        except OSError:
            continue  # vanished meanwhile
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # held by a live process
        finally:
            os.close(fd)
        for f in (base, el, shm / f"sem.{base.name}_mutex"):
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

    def __enter__(self) -> "ChildProcess":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
