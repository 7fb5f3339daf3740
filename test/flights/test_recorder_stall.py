"""A recorder descheduled for a second still records the whole flight (docs/reliability.md, "Delivery").

The launcher's process (which holds the recorder) is stopped with SIGSTOP for 1 s, four times, while a
lockstep flight runs flat out. Messages the transport drops meanwhile are re-sent only once the
writer's next heartbeat (Fast DDS: every 3 s) has made the recorder ask for them, so the writers'
and the recorder's histories must hold rate x (stall + 3 s). With the old depths (1000 / 2000) such
a stall lost 1-10 messages each time; the bag is checked here with the independent mcap reader.
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

from lander_ros.delivery import OUTPUT_DEPTH

from .flightcheck import drain, start_fly, wait_line
from .spancheck import check_span

STALL = 1.0  # s: how long the recorder's process is stopped each time
STALLS = 4
# A flight long enough for the stalls and 3 s of repair after the last: the 200 km orbit's first
# 1500 s (the de-orbit slew, burn and coast) run at 40-120x real time flat out in lockstep, 13-40 s of wall.
SCRIPT = """
name: stalled-recorder
scene: deorbit-200km
controller: deorbit
speed: 0
lockstep: true
sim: {publish_rate: 10.0, lockstep_timeout: 30.0}
end: {time: 1500.0}
timeline:
  - {t: 0, demand_altitude: 500.0}
  - {t: 20, demand_altitude: 501.0}
"""


def test_a_recorder_stopped_for_a_second_loses_nothing(tmp_path: Path) -> None:
    # 10 Hz at up to ~120x real time: ~1200 messages/s per topic, for the stall and 3 s of repair
    assert OUTPUT_DEPTH >= 1200 * (STALL + 3.0)
    (tmp_path / "f.yaml").write_text(SCRIPT)
    bag = tmp_path / "bag"
    proc, lines = start_fly(tmp_path / "f.yaml", bag)
    log: list[str] = []
    try:
        # the timeline's action at t = 20 s: the flight is under way
        wait_line(lines, r"\[fly\] t = [\d.]+ s: demand_altitude 501", log, timeout=120.0)
        stalls_in_flight = 0
        for _ in range(STALLS):
            os.kill(proc.pid, signal.SIGSTOP)
            time.sleep(STALL)  # the fault injected: the recorder's process off the CPU for STALL s
            os.kill(proc.pid, signal.SIGCONT)
            time.sleep(1.0)  # its spacing
            stalls_in_flight += proc.poll() is None
        rc = proc.wait(timeout=300)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGCONT)
            proc.kill()
    out = drain(lines, log)
    assert rc == 0, out
    assert stalls_in_flight == STALLS, f"the flight ended before its stalls were over:\n{out}"
    assert "complete: every message published in the flight is in it" in out, out
    check_span(bag, 1500.0, lockstep=True, sim_only_events=False)
