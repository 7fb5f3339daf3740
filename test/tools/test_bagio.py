"""Bag reading (lander_tools.bagio) on bags written here with rosbags: both storages, types from
the bag's own definitions, sim-time mapping, and damaged bags (partial read or a clear error)."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from lander_tools.bagio import BagError, BagWarning, lander_typestore, read_bag

from .synth import write_flight_bag


def _ramp(n: int = 200, dt: float = 0.1):
    t = np.arange(n) * dt
    return t, 500.0 + 0.5 * t, np.full(n, 0.5)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_round_trip_gives_the_written_series_in_both_storages(tmp_path: Path, storage: str) -> None:
    t, h, hd = _ramp()
    write_flight_bag(tmp_path / "b", t, h, hd, demand=[(0.0, 500.0), (5.05, 510.0)], storage=storage)
    bag = read_bag(tmp_path / "b")
    assert bag.storage == storage and not bag.warnings
    assert bag.counts() == {"/clock": 200, "/lander/demand_altitude": 2, "/lander/state": 200}
    s = bag.series("/lander/state")
    # Values pass through CDR unchanged: float64 in, float64 out, so exact equality holds.
    np.testing.assert_array_equal(s["altitude"], h)
    np.testing.assert_allclose(s["t"], t, atol=1e-9)  # stamps are rounded to whole ns
    assert s["throttles"].shape == (200, 4) and s["euler_zxz"].shape == (200, 3)
    # Header-less demand: placed at the sim time mapped through /clock (bag time = sim + 1 s);
    # the second demand lies between two clock ticks, so linear interpolation is exact here.
    d = bag.series("/lander/demand_altitude")
    np.testing.assert_allclose(d["t"], [0.0, 5.05], atol=1e-9)
    np.testing.assert_array_equal(d["data"], [500.0, 510.0])


def test_types_come_from_the_bag_itself(tmp_path: Path) -> None:
    """A reader with no access to lander_interfaces still decodes: the MCAP schemas carry the .msg text."""
    t, h, hd = _ramp(20)
    write_flight_bag(tmp_path / "b", t, h, hd)
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "b"]) as r:
        assert "lander_interfaces/msg/LanderState" in r.typestore.fielddefs
        defs = {c.topic: c.msgdef.data for c in r.connections}
    assert "PHASE_CRASHED" in defs["/lander/state"]
    # The rosbags hash of our definition equals the one rosidl computes (ros2-from-pypi notes).
    assert lander_typestore().hash_rihs01("lander_interfaces/msg/LanderState").startswith("RIHS01_")


def test_truncated_mcap_is_read_up_to_the_damage_with_a_warning(tmp_path: Path) -> None:
    # 6000 states (~2.4 MB) span several 1 MiB chunks; cutting the file inside the last chunk
    # and removing metadata.yaml is what a recorder killed with SIGKILL leaves.
    n = 6000
    t, h, hd = np.arange(n) * 0.1, np.full(n, 500.0), np.zeros(n)
    write_flight_bag(tmp_path / "b", t, h, hd)
    f = next((tmp_path / "b").glob("*.mcap"))
    data = f.read_bytes()
    f.write_bytes(data[: int(len(data) * 0.8)])
    (tmp_path / "b" / "metadata.yaml").unlink()
    with pytest.warns(BagWarning, match="truncated or damaged"):
        bag = read_bag(tmp_path / "b")
    got = bag.counts()["/lander/state"]
    # Whole chunks before the cut survive: at least half the states, never more than written.
    assert n // 2 <= got < n
    s = bag.series("/lander/state")
    np.testing.assert_array_equal(s["sequence"], np.arange(1, got + 1))  # a prefix, in order


@pytest.mark.parametrize("content", [b"", b"not a bag at all" * 100])
def test_garbage_is_a_clear_error(tmp_path: Path, content: bytes) -> None:
    d = tmp_path / "junk"
    d.mkdir()
    (d / "junk.mcap").write_bytes(content)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagWarning)
        with pytest.raises(BagError, match="junk"):
            read_bag(d)


def test_missing_path_and_missing_topic_are_named(tmp_path: Path) -> None:
    with pytest.raises(BagError, match="bag not found: .*nowhere"):
        read_bag(tmp_path / "nowhere")
    t, h, hd = _ramp(5)
    write_flight_bag(tmp_path / "b", t, h, hd)
    with pytest.raises(BagError, match="no topic '/lander/odom'.*the bag has: /clock"):
        read_bag(tmp_path / "b").series("/lander/odom")
