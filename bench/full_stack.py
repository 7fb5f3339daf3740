"""Benchmark: sustained speed of the full stack (sim + autopilot + recorder) flying scenario 7.

Each variant is one real ``lander fly`` (the user's command, in a subprocess) at speed 0
(as fast as possible) in lockstep, recording ``/clock``, ``/lander/state``, ``/lander/throttle``,
``/autopilot/status`` and ``/diagnostics``:

* ``multi-process``: sim and autopilot in their own processes, the recorder in the launcher's;
* ``composed`` (``--compose``): sim and autopilot in one process and one executor.

Figures, all over the flying part (from the state after the reset to the flight's end time):

* achieved real-time factor: sim seconds per wall second, from the recorder's receive times;
* control-loop latency: recorder receive time of the command answering state N minus that of
  state N (both wall clock, one process): publish of the state -> controller -> command on the wire;
* CPU per process (``/proc/<pid>/stat`` utime + stime, sampled every 0.1 s) in % of one core
  over the same window, and peak RSS (``/proc/<pid>/status``);
* messages lost: state sequence numbers missing from the bag, states (before the end) without
  their command, and the sim's ``lockstep_timeouts`` (a command that did not come in time).

    python bench/full_stack.py [--json F] [--quick] [--scene hover] [--duration S]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

from lander_tools.stack_meter import Sampler, fly_recorded, loop_figures


def run_variant(scene: str, duration: float, compose: bool, folder: Path) -> dict:
    bag = folder / ("composed" if compose else "multi")
    sampler = Sampler()
    rc, out = fly_recorded(scene, duration, compose, bag, sampler=sampler)
    series = sampler.stop()
    if rc != 0:
        raise RuntimeError(f"lander fly exited with {rc}:\n{out[-3000:]}")
    f = loop_figures(bag)
    w0, w1 = f.window_wall
    cpu = {name: s.cpu_percent(w0, w1) for name, s in series.items()}
    rss = {name: max(s.rss) / 2**20 if s.rss else float("nan") for name, s in series.items()}
    return {"variant": "composed" if compose else "multi-process", **asdict(f), "cpu_percent": cpu, "rss_mib_peak": rss}


def format_table(rows: list[dict]) -> str:
    names = ("launcher+recorder", "sim", "autopilot", "composed")

    def cpu(r: dict) -> str:
        return ", ".join(f"{n} {r['cpu_percent'][n]:.0f}%" for n in names if n in r["cpu_percent"])

    head = (f"{'variant':<14} {'sim s':>6} {'wall s':>6} {'RTF':>6} {'lat p50':>8} {'lat p99':>8} {'lat max':>8} "
            f"{'rx gap':>8} {'lost st':>7} {'lost cmd':>8} {'ls t/o':>6}  CPU per process (% of one core)")
    out = [head, "-" * len(head)]
    for r in rows:
        out.append(f"{r['variant']:<14} {r['sim_s']:6.1f} {r['wall_s']:6.1f} {r['rtf']:6.1f} "
                   f"{r['latency_ms_p50']:6.2f}ms {r['latency_ms_p99']:6.2f}ms {r['latency_ms_max']:6.2f}ms "
                   f"{r['rx_gap_ms_max']:6.1f}ms {r['states_missing']:7d} {r['commands_missing']:8d} "
                   f"{'?' if r['lockstep_timeouts'] is None else r['lockstep_timeouts']:>6}  {cpu(r)}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    ap.add_argument("--quick", action="store_true", help="30 s of sim time per variant instead of 120 s")
    ap.add_argument("--scene", default="hover", help="scene (default: hover, scenario 7)")
    ap.add_argument("--duration", type=float, help="sim seconds per variant (overrides --quick)")
    a = ap.parse_args(argv)
    duration = a.duration or (30.0 if a.quick else 120.0)  # scenario 7 runs out of fuel at ~139 s
    # Isolated from whatever else runs on this machine: own domain, loopback only.
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with tempfile.TemporaryDirectory(prefix="full-stack-") as tmp:
        rows = [run_variant(a.scene, duration, compose, Path(tmp)) for compose in (False, True)]
    print(f"full stack (sim + autopilot + recorder), scene {a.scene}, {duration:g} s sim, speed 0, lockstep, "
          f"{os.cpu_count()} cores")
    print(format_table(rows))
    print("latency: recorder receive time of the command answering state N minus that of state N; "
          "rx gap: longest gap between states received by the recorder; lost st: state sequence gaps in the bag; lost cmd: states without their command; "
          "ls t/o: sim's lockstep_timeouts (last diagnostics)")
    if a.json:
        a.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
