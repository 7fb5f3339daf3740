"""Broken scene files and corrupt bags: a clear one-line error naming the file, never a traceback.

From the command line (``lander fly`` / ``lander analyse`` in a subprocess, exit status 2), and in
volume in-process: hypothesis mutates valid files byte by byte and the readers must either read
them or raise their documented ValueError subclass (SceneError / BagError), nothing else.
"""
from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lander_sim.scenes import SceneError, load_scene
from lander_tools.bagio import BagError, BagWarning, read_bag

from .conftest import PROFILE
from .stack import REPO

HOVER = (REPO / "lander_sim" / "scenes" / "hover.yaml").read_bytes()

BROKEN_SCENES = {
    "syntax": b"name: x\nvehicle: {preset: lander\n",
    "list": b"- 1\n- 2\n",
    "unknown_key": HOVER + b"\nwarp_drive: {}\n",
    "bad_type": HOVER.replace(b"dt: 0.1", b"dt: fast"),
    "binary": bytes(range(256)) * 4,
    "empty": b"",
}


def _lander(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=timeout, env=dict(os.environ, PYTHONPATH=str(REPO)))


def _one_line_error(res: subprocess.CompletedProcess, names: str) -> None:
    assert res.returncode == 2, res.stdout + res.stderr
    assert "Traceback" not in res.stderr + res.stdout
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1, res.stderr
    assert names in lines[0], lines[0]



@pytest.mark.parametrize("kind", sorted(BROKEN_SCENES))
def test_lander_fly_on_a_broken_scene_is_a_one_line_error(kind: str, tmp_path: Path) -> None:
    path = tmp_path / f"broken-{kind}.yaml"
    path.write_bytes(BROKEN_SCENES[kind])
    _one_line_error(_lander("fly", str(path), "--no-progress"), path.name)


def _write_bag(path: Path) -> Path:
    """A small valid flight bag (synthetic, closed form) to corrupt."""
    from tools.synth import write_flight_bag  # test/ is on sys.path (root conftest)

    t = np.linspace(0.0, 5.0, 51)
    write_flight_bag(path, t, 500.0 + 0.0 * t, 0.0 * t)
    return path


@pytest.mark.parametrize("damage", ["garbage_mcap", "truncated", "no_files", "bad_metadata"])
def test_lander_analyse_on_a_corrupt_bag_is_a_one_line_error(damage: str, tmp_path: Path) -> None:
    bag = _write_bag(tmp_path / "bag")
    mcap = next(bag.glob("*.mcap"))
    if damage == "garbage_mcap":
        mcap.write_bytes(os.urandom(4096))
        (bag / "metadata.yaml").unlink()
    elif damage == "truncated":
        mcap.write_bytes(mcap.read_bytes()[:40])
        (bag / "metadata.yaml").unlink()
    elif damage == "no_files":
        for f in bag.iterdir():
            f.unlink()
    else:
        (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [this is: not, metadata\n")
        mcap.write_bytes(b"\x89MCAP0\r\n")
    res = _lander("analyse", str(bag))
    if res.returncode == 0:  # read what could be read: only acceptable with a warning
        assert "warn" in (res.stderr + res.stdout).lower()
        return
    _one_line_error(res, "bag")


@settings(PROFILE, max_examples=60)
@given(st.data())
def test_mutated_scene_files_load_or_raise_scene_error(tmp_path_factory: pytest.TempPathFactory, data) -> None:
    raw = bytearray(HOVER)
    for _ in range(data.draw(st.integers(1, 8))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(raw)))
    path = tmp_path_factory.mktemp("scene") / "mutated.yaml"
    path.write_bytes(bytes(raw[:cut]))
    try:
        load_scene(str(path))
    except SceneError as exc:
        assert "mutated.yaml" in str(exc)  # names the file


@settings(PROFILE, max_examples=60)
@given(st.data())
def test_mutated_bags_read_or_raise_bag_error(tmp_path_factory: pytest.TempPathFactory, data) -> None:
    bag = _write_bag(tmp_path_factory.mktemp("bag") / "bag")
    mcap = next(bag.glob("*.mcap"))
    raw = bytearray(mcap.read_bytes())
    for _ in range(data.draw(st.integers(1, 8))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    mcap.write_bytes(bytes(raw[: data.draw(st.integers(0, len(raw)))]))
    if data.draw(st.booleans()):
        (bag / "metadata.yaml").unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagWarning)
        try:
            read_bag(bag)
        except BagError as exc:
            assert str(bag) in str(exc) or "mcap" in str(exc)
