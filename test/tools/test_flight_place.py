"""Where a flight runs and whom it listens to, without the middleware: the domain and discovery
range a flight takes (lander_tools.fly.domain), the run file the verbs find it by, the sender
check of a launched flight's inputs (lander_ros.strangers) and the bag check's two kinds of wrong
count (lander_ros.flight_span)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from lander_ros.flight_span import shortfalls, surplus
from lander_ros.strangers import STRANGER_KIND, InputGuard, gid_of, with_message_info
from lander_tools.fly import domain as place


@dataclass
class Endpoint:  # the fields of rclpy's TopicEndpointInfo the guard reads
    node_name: str
    node_namespace: str
    endpoint_gid: list[int]


def info(gid: bytes) -> dict:
    return {"publisher_gid": {"implementation_identifier": "rmw_fastrtps_cpp", "data": gid}}


AUTOPILOT, LAUNCHER, OTHER_AUTOPILOT, SCRIPT, VERB = (bytes([k]) * 16 for k in range(1, 6))


def graph(*pubs: tuple[bytes, str]):
    return lambda: [Endpoint(name.rsplit("/", 1)[1], "/", list(gid)) for gid, name in pubs]


def test_a_launched_flight_takes_its_own_nodes_and_the_verbs_and_refuses_strangers_once() -> None:
    g = InputGuard(True)
    everyone = graph((AUTOPILOT, "/autopilot"), (LAUNCHER, "/lander_fly"), (OTHER_AUTOPILOT, "/autopilot"),
                     (SCRIPT, "/my_script"), (VERB, "/lander_live"))
    assert g.refusal(info(AUTOPILOT), everyone) is None  # first heard: the flight's autopilot
    assert g.refusal(info(LAUNCHER), everyone) is None
    assert g.refusal(info(VERB), everyone) is None  # the user's lander verbs
    first = g.refusal(info(OTHER_AUTOPILOT), everyone)  # a second /autopilot: another flight's
    assert first and "/autopilot" in first and "second flight" in first and STRANGER_KIND in first
    assert g.refusal(info(OTHER_AUTOPILOT), everyone) == ""  # later ones counted, not announced
    assert "/my_script" in (g.refusal(info(SCRIPT), everyone) or "")
    assert g.refusal(info(AUTOPILOT), everyone) is None


def test_a_sim_alone_flight_refuses_any_autopilot_and_an_unlaunched_sim_takes_everyone() -> None:
    pubs = graph((OTHER_AUTOPILOT, "/autopilot"))
    assert InputGuard(True, ("/lander_fly",)).refusal(info(OTHER_AUTOPILOT), pubs)
    assert InputGuard(False).refusal(info(OTHER_AUTOPILOT), pubs) is None


def test_a_publisher_the_graph_does_not_name_yet_is_taken_only_before_the_flights_own_is_heard() -> None:
    g = InputGuard(True, ("/lander_sim",), "/lander/state", verbs=False)
    empty = graph()
    assert g.refusal(info(AUTOPILOT), empty) is None  # maybe the flight's own: taken, judged again later
    assert g.refusal(info(AUTOPILOT), graph((AUTOPILOT, "/lander_sim"))) is None  # now the owner
    assert g.refusal(info(OTHER_AUTOPILOT), empty) == ""  # a newcomer: refused until named
    assert g.refusal(info(OTHER_AUTOPILOT), graph((AUTOPILOT, "/lander_sim"), (OTHER_AUTOPILOT, "/lander_sim")))


def test_an_endpoint_listed_before_its_node_is_known_is_not_judged_by_its_placeholder_name() -> None:
    g = InputGuard(True)
    unnamed = lambda: [Endpoint("_NODE_NAME_UNKNOWN_", "_NODE_NAMESPACE_UNKNOWN_", list(AUTOPILOT))]  # noqa: E731
    assert g.refusal(info(AUTOPILOT), unnamed) is None  # maybe the flight's autopilot: taken, not judged
    assert g.refusal(info(AUTOPILOT), graph((AUTOPILOT, "/autopilot"))) is None
    assert g.refusal(info(SCRIPT), lambda: [Endpoint("_NODE_NAME_UNKNOWN_", "_NODE_NAMESPACE_UNKNOWN_",
                                                     list(SCRIPT))]) == ""  # a newcomer: refused until named
    assert "/my_script" in (g.refusal(info(SCRIPT), graph((SCRIPT, "/my_script"))) or "")


def test_the_owner_of_a_name_may_be_replaced_once_it_left_the_graph() -> None:
    g = InputGuard(True)
    assert g.refusal(info(AUTOPILOT), graph((AUTOPILOT, "/autopilot"))) is None
    assert g.refusal(info(OTHER_AUTOPILOT), graph((OTHER_AUTOPILOT, "/autopilot"))) is None  # restarted


def test_the_callback_wrapper_takes_both_calling_conventions_and_says_it_wants_the_info() -> None:
    import inspect

    got = []
    cb = with_message_info(lambda msg, i: got.append((msg, gid_of(i))))
    assert len(inspect.signature(cb).parameters) == 2  # rclpy then hands the MessageInfo
    cb("m", info(VERB))  # rclpy's standard executors
    cb(("m", info(VERB)))  # its EventsExecutor: one tuple
    assert got == [("m", VERB), ("m", VERB)]


def test_the_bag_check_tells_extra_messages_from_missing_ones() -> None:
    reference = {"/clock": (601, True), "/lander/state": (601, True), "/autopilot/status": (10, False)}
    recorded = {"/clock": 637, "/lander/state": 600, "/autopilot/status": 50}
    assert shortfalls(reference, recorded) == ["/lander/state 600 of 601"]
    assert surplus(reference, recorded) == ["/clock 637 of 601"]  # at-least topics have no surplus


@pytest.fixture
def own_locks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The domain locks and run files in a folder of this test's own."""
    monkeypatch.setattr(place, "LOCK_DIR", tmp_path / "locks")
    monkeypatch.setattr(place, "TEST_LOCK_DIR", tmp_path / "test-locks")
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "run"))
    return tmp_path


def test_a_flight_takes_the_users_domain_and_range_else_a_free_domain_on_localhost(own_locks: Path) -> None:
    p, lock = place.choose_place({"ROS_DOMAIN_ID": "42", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert (p.domain, p.discovery, p.domain_from, lock.domain) == (42, "SUBNET", "ROS_DOMAIN_ID", 42)
    lock.release()
    p, lock = place.choose_place({"ROS_DOMAIN_ID": "42"}, domain=7, network=True)
    assert (p.domain, p.discovery, p.domain_from, lock.domain) == (7, "SUBNET", "--domain", 7)
    lock.release()
    a, lock_a = place.choose_place({})
    b, lock_b = place.choose_place({})
    try:
        assert a.discovery == b.discovery == "LOCALHOST"
        assert a.domain != b.domain and all(place.DOMAIN_MIN <= d <= place.DOMAIN_MAX for d in (a.domain, b.domain))
        assert a.env() == {"ROS_DOMAIN_ID": str(a.domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    finally:
        for lk in (lock_a, lock_b):
            assert lk is not None
            lk.release()
    again, lock_c = place.choose_place({})
    assert lock_c is not None and again.domain == a.domain  # released: free again
    lock_c.release()
    with pytest.raises(ValueError, match="ROS_DOMAIN_ID = 'x'"):
        place.choose_place({"ROS_DOMAIN_ID": "x"})


def test_a_domain_the_user_chose_is_refused_while_another_flight_here_holds_it(own_locks: Path) -> None:
    """Two ``lander fly`` on one machine in the user's one domain: the second is refused before it
    starts anything (no discovery to wait for), in the words of the graph's refusal."""
    p, held = place.choose_place({"ROS_DOMAIN_ID": "9"})
    try:
        with pytest.raises(place.DomainTaken, match=r"another flight is running in ROS_DOMAIN_ID=9 \(another lander fly"):
            place.choose_place({"ROS_DOMAIN_ID": "9"})
        with pytest.raises(place.DomainTaken):
            place.choose_place({}, domain=9)
        _, lock = place.choose_place({"ROS_DOMAIN_ID": "10"})  # another domain is free
        lock.release()
        free, lock = place.choose_place({})
        assert free.domain != 9  # a held domain is never picked either
        lock.release()
    finally:
        held.release()
    again, lock = place.choose_place({"ROS_DOMAIN_ID": "9"})  # the flight ended: its domain is free
    lock.release()


def test_a_domain_a_test_run_holds_is_never_picked(own_locks: Path) -> None:
    import fcntl

    first = place.claim_free_domain(start=0)
    taken = first.domain
    first.release()
    (own_locks / "test-locks").mkdir()
    held = open(own_locks / "test-locks" / f"{taken}.lock", "w")
    fcntl.flock(held, fcntl.LOCK_EX)
    try:
        lock = place.claim_free_domain(start=0)
        assert lock.domain != taken
        lock.release()
    finally:
        held.close()


def test_the_verbs_find_the_users_newest_flight_and_keep_an_explicit_domain(own_locks: Path) -> None:
    env: dict[str, str] = {}
    assert place.attach_env(env) == place.Attachment(None) and env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    first = place.write_run_file(place.FlightPlace(11, "LOCALHOST", "picked", "default"), "hover")
    env = {}
    found = place.attach_env(env)
    assert found.note is None and found.flight and found.flight.domain == 11 and env["ROS_DOMAIN_ID"] == "11"
    # A second flight, started later: the newest.
    d = json.loads(first.read_text())
    d.update(domain=12, scene="landing", started=d["started"] + 1.0)
    second = first.with_name("flight-1.json")
    second.write_text(json.dumps(d))
    env = {}
    note = place.attach_env(env).note
    assert env["ROS_DOMAIN_ID"] == "12" and note and "'landing' in ROS_DOMAIN_ID=12" in note and "'hover' in 11" in note
    env = {"ROS_DOMAIN_ID": "3", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    assert place.attach_env(env) == place.Attachment(None)  # no flight of the user's in domain 3
    assert env == {"ROS_DOMAIN_ID": "3", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    env = {"ROS_DOMAIN_ID": "11"}
    assert (found := place.attach_env(env)).flight and found.flight.scene == "hover"  # the user's own, named
    # A launcher that died leaves its file: it is not a running flight.
    d["pid"] = 2**22 + 12345  # above Linux's pid_max default: no such process
    second.write_text(json.dumps(d))
    assert [f.domain for f in place.running_flights()] == [11] and not second.exists()
