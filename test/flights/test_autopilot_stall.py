"""An autopilot stopped mid-flight in lockstep: the sim advances without it, and says so.

The autopilot's process is stopped with SIGSTOP for longer than the sim's ``lockstep_timeout``, so
the sim advances past states without their answer (each one a lockstep timeout). The flight is then
not the deterministic one, but its bag still holds every message published: the answers the
autopilot never sent are not "missing from the bag". The sim's ``FLIGHT_ENDED`` counts the
timeouts (lander_ros.flight_span), the launcher's bag check expects one answer per state less those,
and its summary and ``lander analyse`` name them. Before that count existed the check reported the unsent answers as
published and lost (docs/reliability.md, "Delivery").
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

from .flightcheck import drain, lander, start_fly, wait_line
from .spancheck import check_span

TIMEOUT = 0.5  # s: the sim's lockstep_timeout in this flight
STALL = 2.0  # s: how long the autopilot's process is stopped (several timeouts)
# The 200 km orbit's first 300 s (the slew, the burn from t = 60 s and the coast's start) run at
# 40-120x real time flat out in lockstep: 3-8 s of wall, and the stall after the burn's start halts
# the flight for its length (the sim advances one state per timeout meanwhile), so it ends in flight.
SCRIPT = f"""
name: stalled-autopilot
scene: deorbit-200km
controller: deorbit
speed: 0
lockstep: true
sim: {{publish_rate: 10.0, lockstep_timeout: {TIMEOUT}}}
end: {{time: 300.0}}
timeline:
  - {{t: 0, demand_altitude: 500.0}}
  - {{t: 20, demand_altitude: 501.0}}
"""


def test_a_stalled_autopilot_is_named_and_its_bag_is_still_whole(tmp_path: Path) -> None:
    (tmp_path / "f.yaml").write_text(SCRIPT)
    bag = tmp_path / "bag"
    proc, lines = start_fly(tmp_path / "f.yaml", bag)
    log: list[str] = []
    try:
        pid = int(wait_line(lines, r"\[fly\] scene .* pids .*autopilot (\d+)", log, timeout=120.0).group(1))
        # under way, and not at a timeline action (the launcher holds the sim there until the
        # autopilot has the new demand, which a stall would only lengthen): the burn's start at t = 60 s
        wait_line(lines, r"event at t = [\d.]+ s: .* -> 'deorbit-burn'", log, timeout=120.0)
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(STALL)  # the fault injected: the autopilot off the CPU for several lockstep timeouts
        finally:
            os.kill(pid, signal.SIGCONT)
        stalled_in_flight = proc.poll() is None
        rc = proc.wait(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    out = drain(lines, log)
    assert stalled_in_flight, f"the flight ended before the stall was over:\n{out}"
    assert rc == 0, out
    assert "complete: every message published in the flight is in it" in out, out
    span = check_span(bag, 300.0, lockstep=False, sim_only_events=False)
    missed = span.end.lockstep_timeouts
    # the stall alone gives one timeout per TIMEOUT s (the sim publishes the next state at once); a
    # loaded machine may add others, so only the floor is the stall's
    assert missed >= int(STALL / TIMEOUT) - 1, f"{missed} lockstep timeouts for a {STALL} s stall:\n{out}"
    assert f"the sim advanced past {missed} states without the autopilot's answer" in out, out
    states, answered = set(span.state_seq), set(span.answers)
    assert answered <= states
    # every state is answered but those the sim advanced past (an answer may still come after its timeout)
    assert len(states - answered) <= missed, (len(states - answered), missed)
    # and the bag tells it: lander analyse names the timeouts
    analysed = lander("analyse", str(bag))
    assert analysed.returncode == 0, analysed.stderr
    assert f"the sim advanced past {missed} states without the autopilot's answer" in analysed.stderr, analysed.stderr
