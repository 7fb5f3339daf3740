"""Test isolation itself: private domain, localhost discovery, clean-up of dead processes' shm."""

import math
import os
import re
import signal
import time
import uuid
from pathlib import Path

import rosutil

HERE = Path(__file__).resolve().parent
SEGMENT = re.compile(r"fastdds_[0-9a-f]{16}$")  # a participant's own segment (ports are shared)
START_TIMEOUT_S = 30.0  # a Python child importing rclpy on 2 busy cores; the wait ends early
MIN_AGE_S = 2.0  # the clean-up's default: younger files may be another run's, its lock not yet taken


def _own_segments(pid: int) -> set[Path]:
    """The participant segments process ``pid`` has mapped: its own, not those of other runs on
    the machine (the other xdist worker, another engineer's suite) created meanwhile."""
    try:
        maps = Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return set()
    return {Path(m) for m in re.findall(r"(/dev/shm/fastdds_\S+)", maps) if SEGMENT.match(Path(m).name)}


def _age(f: Path) -> float:
    """Seconds since ``f`` was written; infinite once it is gone (another run's clean-up took it)."""
    try:
        return time.time() - f.stat().st_mtime
    except FileNotFoundError:
        return math.inf


def test_run_has_private_domain_and_localhost_discovery():
    domain = int(os.environ["ROS_DOMAIN_ID"])
    assert rosutil.DOMAIN_MIN <= domain <= rosutil.DOMAIN_MAX  # never 0, the default of stray nodes
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_domain_claims_are_distinct_while_held():
    """Two claims starting from the same seed must not collide (the lock walks to a free id)."""
    own = int(os.environ["ROS_DOMAIN_ID"])
    a = rosutil.claim_domain_id(seed=own)
    b = rosutil.claim_domain_id(seed=own)
    try:
        assert len({own, a, b}) == 3
    finally:
        rosutil.release_domain_id(a)
        rosutil.release_domain_id(b)


def test_a_domain_a_users_flight_holds_is_never_claimed_by_a_test():
    """`lander fly` holds its domain by a lock (lander_tools.fly.domain); a test claiming domains
    walks past it, as two test runs walk past each other's."""
    from lander_tools.fly.domain import hold_domain

    own = int(os.environ["ROS_DOMAIN_ID"])
    first = rosutil.claim_domain_id(seed=own)
    rosutil.release_domain_id(first)  # the id the next claim from this seed would take
    flight = hold_domain(first)
    try:
        claimed = rosutil.claim_domain_id(seed=own)
        rosutil.release_domain_id(claimed)
        assert claimed != first
    finally:
        flight.release()


def test_shm_of_killed_process_is_cleaned_and_live_one_kept(spawn_python):
    prefix = f"/iso_{uuid.uuid4().hex[:8]}"
    victim = spawn_python([str(HERE / "sample_node.py"), prefix], name="victim")
    rosutil.wait_for(lambda: _own_segments(victim.proc.pid), START_TIMEOUT_S, what="victim's shm segment")
    victim_files = _own_segments(victim.proc.pid)
    victim.proc.send_signal(signal.SIGKILL)  # no chance to clean up: leaves its files behind
    victim.proc.wait()
    assert all(f.exists() for f in victim_files)

    survivor = spawn_python([str(HERE / "sample_node.py"), prefix + "_b"], name="survivor")
    rosutil.wait_for(lambda: _own_segments(survivor.proc.pid), START_TIMEOUT_S, what="survivor's shm segment")
    survivor_files = _own_segments(survivor.proc.pid)
    assert not survivor_files & victim_files

    # The clean-up's age leaves alone files other runs on the machine are creating now; both
    # processes' files are let reach it, so the survivor's are kept for being held, not young.
    mine = victim_files | survivor_files
    rosutil.wait_for(lambda: min(_age(f) for f in mine) >= MIN_AGE_S, 10.0, what="the segments' age")
    # Segments only, as at a module's end: the dead ports may be being taken over by another run.
    removed = set(rosutil.clean_stale_fastdds_shm(min_age_s=MIN_AGE_S, zombie_ports=False))
    # Gone: by this clean-up, or by another run's that came first (the other xdist worker cleans at
    # each module's end), so the test cannot insist they are all in `removed`.
    assert not any(f.exists() for f in victim_files)
    assert not removed & survivor_files and all(f.exists() for f in survivor_files), "a live process's shm segment was removed"
    assert survivor.returncode is None


def test_a_port_file_without_a_live_lock_is_removed_and_a_held_one_kept(tmp_path: Path):
    # A process killed while creating a port leaves an empty file and no lock file; a participant
    # that later picks that port spins forever waiting for it to be initialised.
    import fcntl

    dead = tmp_path / "fastdds_port7000"
    dead.write_bytes(b"")
    (tmp_path / "sem.fastdds_port7000_mutex").write_bytes(b"\0" * 32)
    live = tmp_path / "fastdds_port7001"
    live.write_bytes(b"\0" * 64)
    lock = open(tmp_path / "fastdds_port7001_sl", "w")
    fcntl.flock(lock, fcntl.LOCK_SH)  # a live shared listener
    unknown = tmp_path / "fastdds_notes"  # neither a port nor a segment with a lock: not ours to judge
    unknown.write_text("x")
    try:  # as at each module's end: the half-made port goes even though others may be starting
        removed = rosutil.clean_stale_fastdds_shm(tmp_path, min_age_s=0.0, zombie_ports=False)
    finally:
        lock.close()
    assert set(removed) == {dead, tmp_path / "sem.fastdds_port7000_mutex"}
    assert live.exists() and unknown.exists()


def test_a_dead_port_with_its_lock_file_is_left_to_fast_dds_while_others_may_open_it(tmp_path: Path):
    # A SIGKILLed participant's port keeps its lock file, unheld; the next participant to pick that
    # number takes it over. Only the full clean-up (a run's start and end) removes it.
    port = tmp_path / "fastdds_port7002"
    port.write_bytes(b"\0" * 64)
    (tmp_path / "fastdds_port7002_el").write_bytes(b"")
    segment = tmp_path / "fastdds_0123456789abcdef"
    segment.write_bytes(b"\0" * 64)
    (tmp_path / "fastdds_0123456789abcdef_el").write_bytes(b"")
    removed = rosutil.clean_stale_fastdds_shm(tmp_path, min_age_s=0.0, zombie_ports=False)
    assert set(removed) == {segment, tmp_path / "fastdds_0123456789abcdef_el"}
    assert port.exists()
    removed = rosutil.clean_stale_fastdds_shm(tmp_path, min_age_s=0.0)
    assert set(removed) == {port, tmp_path / "fastdds_port7002_el"}


def _starts_ros(path: Path) -> list[str]:
    """What in a test file's code (not its docstrings) starts ROS participants: rclpy imported (but
    for its serialisation) or required, the ROS fixtures taken, the flight starters imported, a
    `lander fly` run."""
    import ast

    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] == "rclpy"]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if mod.split(".")[0] == "rclpy" and mod != "rclpy.serialization":
                found.append(mod)
            found += [a.name for a in node.names if a.name in ("start_fly", "fly_recorded", "Stack")]
        elif isinstance(node, ast.FunctionDef) and node.name.startswith("test"):
            found += [a.arg for a in node.args.args if a.arg in ("ros_node", "ros_context", "spawn_python")]
        elif isinstance(node, ast.Call):
            consts = [a.value for a in node.args if isinstance(a, ast.Constant)]
            if "rclpy" in consts or "fly" in consts:  # pytest.importorskip("rclpy"), _lander("fly", ...)
                found.append(f"a call with {consts[0]!r}")
    return found


def test_every_test_file_that_starts_ros_participants_is_named_a_ros_test():
    """rosutil.ROS_TESTS gives each of them its transports: the shared-memory ones in one
    pytest-xdist worker, the others over UDP alone (see there why); one left out would open
    shared-memory ports beside another worker's. The check reads the code for the usual ways in
    (``_starts_ros``); the node tests' own fixtures (a folder's conftest) it does not follow, which
    is why ROS_TESTS names whole folders."""
    test_dir = HERE.parent
    missed = {}
    for path in sorted(test_dir.rglob("test_*.py")):
        rel = path.relative_to(test_dir).as_posix()
        if not rel.startswith(rosutil.ROS_TESTS) and (why := _starts_ros(path)):
            missed[rel] = why
    assert not missed, f"add these to ROS_TESTS in test/rosutil.py: {missed}"
    # and the check sees them where they are
    for known in ("tools/test_record_command.py", "sweep/test_through_ros.py", "tools/test_headline_flight.py",
                  "reliability/test_determinism.py"):
        assert _starts_ros(test_dir / known), known
