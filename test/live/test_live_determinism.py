"""A lockstep flight is bit-identical with and without `lander fly --live` and a connected client
(the bridge only subscribes). Long (two flights of 30 s sim time and a speed-1 flight): --runslow.
It runs `bench/live.py --quick`, which records both flights' states and compares their bytes."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_flight_is_bit_identical_with_and_without_live(module_ros_domain: int) -> None:
    out = subprocess.run([sys.executable, str(REPO / "bench" / "live.py"), "--quick"], capture_output=True,
                         text=True, timeout=900, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    rows = [line for line in out.stdout.splitlines() if line.strip().startswith(("without", "with live"))]  # right-aligned
    assert len(rows) == 2 and all(" yes " in f" {r} " for r in rows), out.stdout
    client_got = int(rows[1].split()[-1])
    assert client_got > 0, out.stdout  # the client was connected and fed during the flight
