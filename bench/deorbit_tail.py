"""Where a dispersed de-orbit flight's fuel goes after the powered descent: a sweep's cases replayed.

For the cases of a de-orbit sweep (by default its ``--worst`` flights of one controller and
``--others`` drawn at random from the rest) this re-flies each case core-only with the current
code, exactly as the sweep flies it (:func:`lander_tools.sweep.flight.flown_periods`), and prints
how the powered descent ended (the start of the phase ``hover``): its altitude error, climb rate
and ground speed, the attitude law's learnt share of the collective
(:class:`lander_autopilot.controllers.combined.CollectiveHeadroom`), the fuel to there over the
optimum, then the time and fuel to the first instant within the band at rest (the sweep's
``fuel_ratio``). The optimum is the sweep's (``powered_optimum`` in its ``flights.csv``, solved from
the same handover state): valid while the phases before the powered descent are unchanged.

What it shows is what sets the margins of docs/deorbit.md ("Why the numbers"): where a flight
stopped the fall against the band, and how long the hover law took from there to the band at rest.

    ./dev exec python bench/deorbit_tail.py sweeps/deorbit-200km.yaml out/sweep/deorbit-200km/flights.csv
    ./dev exec python bench/deorbit_tail.py sweeps/deorbit-200km.yaml out/sweep/deorbit-200km/flights.csv \
        --controller mpc --cases 188,171
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from multiprocessing import Pool

import numpy as np

from lander_autopilot.controllers import Demand
from lander_autopilot.controllers.deorbit import Phase
from lander_sim.physics import constants as c
from lander_tools.sweep.flight import flown_periods
from lander_tools.sweep.metrics import in_hover_band
from lander_tools.sweep.spec import load_spec

DEMAND = Demand(altitude=500.0)


def replay(args: tuple[str, int, int]) -> tuple[int, dict[str, float] | None]:
    """Fly case ``index`` of the spec with its controller ``ci``; None if it never reached the band."""
    spec_path, ci, index = args
    spec = load_spec(spec_path)
    band, speed = spec.end.hover_band, spec.end.hover_speed
    row: dict[str, float] = {}
    fuel0 = t0 = None
    for t, s, ctrl, sim in flown_periods(spec, ci, index):
        h = float(np.linalg.norm(s.r_W)) - c.MARS_RADIUS
        if ctrl.phase is Phase.POWERED and fuel0 is None:
            fuel0, t0 = s.fuel, t
        if ctrl.phase is Phase.HOVER and fuel0 is not None and t0 is not None:
            if "hover_t" not in row:
                up = s.r_W / float(np.linalg.norm(s.r_W))
                hd = float(s.v_W @ up)
                headroom = getattr(ctrl, "headroom", None) if spec.controllers[ci].name == "deorbit-mpc" else ctrl.descent.headroom
                row.update(wind=float(np.linalg.norm(sim.scene.wind_W)), hover_t=t - t0, error=h - DEMAND.altitude,
                           climb=hd, drift=float(np.linalg.norm(s.v_W - hd * up)), fuel_hover=fuel0 - s.fuel,
                           share=headroom.share if headroom is not None else math.nan)
            if in_hover_band(h - DEMAND.altitude, float(np.linalg.norm(s.v_W)), band, speed):
                row.update(band_t=t - t0, fuel_band=fuel0 - s.fuel)
                return index, row
    return index, None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("spec", help="the sweep's spec (YAML)")
    ap.add_argument("flights", help="that sweep's flights.csv (its fuel_ratio and powered_optimum)")
    ap.add_argument("--controller", default="scheduled", help="the spec's controller label (default: scheduled)")
    ap.add_argument("--cases", help="comma-separated case indices (default: --worst and --others)")
    ap.add_argument("--worst", type=int, default=20)
    ap.add_argument("--others", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1, help="draws the --others")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    spec = load_spec(a.spec)
    labels = [ch.label for ch in spec.controllers]
    if a.controller not in labels:
        ap.error(f"--controller: {a.controller!r} is not one of the spec's {labels}")
    ci = labels.index(a.controller)
    swept = {int(r["index"]): r for r in csv.DictReader(open(a.flights)) if r["controller"] == a.controller}
    if not swept:
        ap.error(f"{a.flights}: no flights of controller {a.controller!r}")
    ratio = {i: float(r["fuel_ratio"]) for i, r in swept.items()}
    if a.cases:
        cases = [int(x) for x in a.cases.split(",")]
    else:
        order = sorted(ratio, key=ratio.get)
        rng = np.random.default_rng(a.seed)
        rest = order[:-a.worst] if a.worst else order
        cases = order[-a.worst:] if a.worst else []
        cases += [int(i) for i in rng.choice(rest, min(a.others, len(rest)), replace=False)]
    with Pool(a.workers) as pool:
        results = dict(pool.map(replay, [(a.spec, ci, i) for i in cases], chunksize=1))
    print("| case | wind [m/s] | swept fuel_ratio | hover phase at [s] | altitude error [m] | climb [m/s] | drift [m/s] "
          "| share | fuel there / optimum | band at rest at [s] | fuel_ratio now |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    now = []
    for i in cases:
        r, opt = results[i], float(swept[i]["powered_optimum"])
        if r is None:
            print(f"| {i} | - | {ratio[i]:.3f} | never in the band at rest | | | | | | | |")
            continue
        now.append(r["fuel_band"] / opt)
        print(f"| {i} | {r['wind']:.1f} | {ratio[i]:.3f} | {r['hover_t']:.1f} | {r['error']:+.2f} | {r['climb']:+.2f} | "
              f"{r['drift']:.2f} | {r['share']:.3f} | {r['fuel_hover'] / opt:.3f} | {r['band_t']:.1f} | {now[-1]:.3f} |")
    f = np.array(now)
    if f.size:
        print(f"\n{f.size} of {len(cases)} in the band: fuel_ratio median {np.median(f):.3f}, mean {f.mean():.3f}, "
              f"max {f.max():.3f}, within 1.05: {int((f <= 1.05).sum())}")
    return 0 if f.size == len(cases) else 1


if __name__ == "__main__":
    sys.exit(main())
