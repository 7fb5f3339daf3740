"""The .msg/.srv files are readable by the rosbags typestore, which recording and analysis use.

Each type is registered from its source file with ``get_types_from_msg`` and checked against the
rosidl build in this venv: the RIHS01 type hash equals the one rosidl generated (so bags written
by rosbags are accepted by ROS 2 tools), and CDR goes both ways: rclpy serialises, rosbags
deserialises to the same values and re-serialises to the same length, and rclpy reads rosbags'
bytes back to the same values. Exact equality is right: both implement the same CDR encoding of
the same IEEE doubles.

Services are checked for CDR only: rosbags has no ``srv`` namespace (it files
``pkg/srv/X_Request`` as ``pkg/srv/msg/X_Request``), so their names, and hence hashes, differ from
rosidl's. Bags record topics, not services, so that does not matter for recording.
"""

import json
from pathlib import Path

import pytest
import samples

ROOT = Path(__file__).resolve().parents[2]
IFACE = ROOT / "lander_interfaces"
PKG = "lander_interfaces"


def _install_share() -> Path:
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory(PKG))


@pytest.fixture(scope="module")
def typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    types = {}
    for name in samples.MESSAGES:
        types.update(get_types_from_msg((IFACE / "msg" / f"{name}.msg").read_text(), f"{PKG}/msg/{name}"))
    for name in samples.SERVICES:
        request, response = (IFACE / "srv" / f"{name}.srv").read_text().split("\n---\n")
        types.update(get_types_from_msg(request, _srv_typename(name, "Request")))
        types.update(get_types_from_msg(response, _srv_typename(name, "Response")))
    store.register(types)
    return store


def _srv_typename(name: str, part: str) -> str:
    return f"{PKG}/srv/msg/{name}_{part}"  # rosbags' spelling of a service part, see above


def _rosidl_hash(kind: str, name: str, typename: str) -> str:
    description = json.loads((_install_share() / kind / f"{name}.json").read_text())
    return {h["type_name"]: h["hash_string"] for h in description["type_hashes"]}[typename]


def test_every_interface_file_is_built_and_sampled():
    """CMakeLists, the sources and these tests name the same set, so none escapes the checks."""
    cmake = (IFACE / "CMakeLists.txt").read_text()
    for kind, names in (("msg", samples.MESSAGES), ("srv", samples.SERVICES)):
        on_disk = sorted(p.stem for p in (IFACE / kind).glob(f"*.{kind}"))
        assert on_disk == sorted(names)
        for n in names:
            assert f'"{kind}/{n}.{kind}"' in cmake


@pytest.mark.parametrize("name", samples.MESSAGES)
def test_message_hash_matches_rosidl(typestore, name):
    typename = f"{PKG}/msg/{name}"
    assert typestore.hash_rihs01(typename) == _rosidl_hash("msg", name, typename)


def _cdr_round_trip(typestore, ros_msg, typename):
    from rclpy.serialization import deserialize_message, serialize_message

    raw = serialize_message(ros_msg)
    bag_msg = typestore.deserialize_cdr(raw, typename)
    assert samples.to_plain(bag_msg) == samples.to_plain(ros_msg)
    again = bytes(typestore.serialize_cdr(bag_msg, typename))
    # Same layout (length); not byte-equal: Fast CDR leaves alignment padding uninitialised,
    # rosbags writes zeros there. The decoded values must be equal.
    assert len(again) == len(raw)
    assert samples.to_plain(deserialize_message(again, type(ros_msg))) == samples.to_plain(ros_msg)


@pytest.mark.parametrize("name", samples.MESSAGES)
def test_message_cdr_round_trip(typestore, name):
    _cdr_round_trip(typestore, samples.make_message(name), f"{PKG}/msg/{name}")


@pytest.mark.parametrize("name", samples.SERVICES)
def test_service_cdr_round_trip(typestore, name):
    request = samples.make_request(name)
    _cdr_round_trip(typestore, request, _srv_typename(name, "Request"))
    _cdr_round_trip(typestore, samples.answer(name, request), _srv_typename(name, "Response"))
