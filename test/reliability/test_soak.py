"""Soak: a long lockstep flight of the full stack (``lander fly``: sim + autopilot + recorder) at
speed 0 with recording: memory bounded, nothing lost, the cost per state steady.

Scene: scenario 0 (circular orbit at 1.2 R) flown by the scenario-7 controller. Scenario 7 itself
cannot fly for an hour: its 100 kg of fuel last about 140 s of hover. In orbit the controller
keeps commanding (and burns its fuel), then the lander coasts; every tick still goes
state -> autopilot -> command -> sim and into the bag, which is what a soak exercises.
Default: 5 simulated minutes; ``--runslow``: one simulated hour.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lander_tools import stack_meter as meter
from lander_tools.bagio import read_bag

from .stack import stamp_s

SCENE = "circular-orbit"
CONTROLLER = "combined-quaternion"
#: Bytes a recorder legitimately keeps per message written (MCAP chunk/message index entries are
#: tens of bytes): a 100 B/message allowance, plus 8 MiB of allocator and cache slack per process.
INDEX_BYTES_PER_MESSAGE = 100
SLACK_BYTES = 8 * 2**20


def _soak(tmp_path: Path, sim_seconds: float) -> None:
    bag = tmp_path / "soak"
    sampler = meter.Sampler(period=0.2)
    rc, out = meter.fly_recorded(SCENE, sim_seconds, False, bag, extra=("--controller", CONTROLLER),
                                 sampler=sampler, timeout=60.0 + sim_seconds)
    series = sampler.stop()
    assert rc == 0, out  # time limit reached while flying
    f = meter.loop_figures(bag)
    b = read_bag(bag, ["/lander/state", "/lander/throttle"])
    states = b.messages("/lander/state")
    seq = np.array([m.sequence for m in states])
    start = int(np.flatnonzero(seq == 1)[-1])
    t = np.array([stamp_s(m.header.stamp) for m in states[start:]])
    # Memory: growth per process from a quarter into the flight to its end, against the bound.
    w0, w1 = f.window_wall
    n_messages = 2 * len(states)
    growths = {}
    for name, s in series.items():
        growth = growths[name] = s.rss_at(w1) - s.rss_at(w0 + 0.25 * (w1 - w0))
        bound = SLACK_BYTES + INDEX_BYTES_PER_MESSAGE * n_messages
        assert growth < bound, f"{name}: RSS grew {growth / 2**20:.1f} MiB (bound {bound / 2**20:.1f} MiB)"
    # The stack's cost per state steady: CPU seconds of all its processes per state in the last
    # quarter at most twice that of the first. A per-tick cost growing with the flight (a leak, an
    # ever-growing list) shows as a trend. CPU time, not wall time: a flat-out flight's real-time
    # factor follows whatever else the machine runs (the other test worker starting a browser or
    # a sweep mid-flight halved it), while the work each state costs its own processes does not.
    rx = np.asarray(b.topics["/lander/state"].t_bag_ns[start:], dtype=float) * 1e-9
    q = len(t) // 4

    def cpu_per_state(i0: int, i1: int) -> float:
        cpu = sum(float(np.diff(np.interp([rx[i0], rx[i1]], s.wall, s.cpu))[0]) for s in series.values())
        return cpu / (i1 - i0)

    cost_first, cost_last = cpu_per_state(0, q), cpu_per_state(len(t) - 1 - q, len(t) - 1)
    rtf_first = (t[q] - t[0]) / (rx[q] - rx[0])
    rtf_last = (t[-1] - t[-q]) / (rx[-1] - rx[-q])
    # The figures (shown with -s; quoted in docs/reliability.md).
    print(f"\nsoak {sim_seconds:.0f} s: {len(states)} states, wall {rx[-1] - rx[0]:.1f} s, RTF first quarter "
          f"{rtf_first:.1f}, last {rtf_last:.1f}, CPU per state first quarter {1e3 * cost_first:.2f} ms, last "
          f"{1e3 * cost_last:.2f} ms, lockstep timeouts {f.lockstep_timeouts}, RSS growth (last 3/4) "
          + ", ".join(f"{n} {g / 2**20:+.1f} MiB" for n, g in growths.items())
          + f" (bound {(SLACK_BYTES + INDEX_BYTES_PER_MESSAGE * n_messages) / 2**20:.1f} MiB)")
    assert set(series) >= {"sim", "autopilot"} and cost_first > 0.0, (sorted(series), cost_first)
    assert cost_last <= 2.0 * cost_first, (cost_first, cost_last)
    # No lost messages: no gap in the state sequence, and every state of the flight proper (after
    # the first second: start-up race of `lander fly`, reported) has its command in the bag.
    assert t[-1] >= sim_seconds - 1e-6
    answered = {m.state_sequence for m in b.messages("/lander/throttle")}
    unanswered = [int(s) for s, ti in zip(seq[start:], t) if 1.0 <= ti < t[-1] and int(s) not in answered]
    if f.states_missing or unanswered:
        warnings = "".join(line for line in out.splitlines(keepends=True) if "WARN" in line or "ERROR" in line)
        raise LostMessages(f"{f.states_missing} states missing from the bag; states without a command: "
                           f"{unanswered[:10]}; sim's lockstep timeouts: {f.lockstep_timeouts}\n{warnings[-3000:]}")


class LostMessages(AssertionError):
    """The bag lacks messages the nodes sent (kept apart from memory and speed failures)."""


def test_soak_five_simulated_minutes(tmp_path: Path) -> None:
    _soak(tmp_path, 300.0)


@pytest.mark.slow
def test_soak_one_simulated_hour(tmp_path: Path) -> None:
    _soak(tmp_path, 3600.0)
