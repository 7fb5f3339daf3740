"""A de-orbit sweep's powered descents, re-flown in a minute: snapshots under the chute, replayed.

A de-orbit sweep (sweeps/deorbit*.yaml) flies 200 flights of 2000-4700 s each to measure what
happens in the last ~20 s: the powered descent and the capture of the hover (``fuel_ratio``,
docs/sweeps.md). Two cores take 14 min (200 km) and 33 min (scenario 0's orbit) for one law. This
tool flies each case once as the sweep does (:func:`lander_tools.sweep.flight.fly_case`'s loop: the
same scene, case, demand and control instants) and pickles the simulation and the controller as
they are at the first control instant under ``--altitude`` (2500 m) in the entry or parachute
phase, well above any braking; ``replay`` loads them and flies the rest with the code as it is now.
Each flight ends at the first instant within the hover band at rest after the powered descent
began (the sweep's ``fuel_ratio`` endpoint), or with ``--hold`` once the hover is held (the
sweep's success: 30 s within the band at rest). A change to the hover law needs ``--hold``: one
that improved every ``fuel_ratio`` made 13 of 200 flights fall from the hover later
(:class:`lander_autopilot.controllers.deorbit.hover.HoverCapture`).

A replay is the sweep's flight, bit for bit, as long as nothing that runs before the snapshot has
changed (the entry, the chute, what the laws learn under it): ``--check K`` re-flies the first K
cases whole with :func:`~lander_tools.sweep.flight.fly_case` and compares. Snapshots made by older
code get the attributes the current controller's ``reset()`` adds, and its design constants (gains,
margins), from a fresh controller.

    ./dev exec python bench/deorbit_replay.py make sweeps/deorbit-200km.yaml --controller scheduled   # 14 min
    ./dev exec python bench/deorbit_replay.py replay sweeps/deorbit-200km.yaml --controller scheduled  # ~30 s
    ./dev exec python bench/deorbit_replay.py replay sweeps/deorbit-200km.yaml --cases 38,140 --check 2

Prints the fuel_ratio percentiles, how many flights are within 1.03 / 1.05 / 1.10 x the optimum
and the worst flights (where the hover began: altitude error, climb rate, ground speed); ``--csv``
writes one row a flight. Beside the sweep's ``fuel_ratio`` (the fuel read at the first control
instant in the band, over the optimum at rest at the demand) and ``fuel_ratio_balanced``: the
band's entry found within its period (``fuel_ratio_entry``, :func:`~lander_tools.sweep.metrics.band_entry_fuel`)
and, with ``--like``, that entry over the optimum to the hover's own tolerance (``fuel_ratio_like``:
the two ends alike; docs/deorbit.md, "The band's entry and the hover's tolerance").
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import math
import os
import pickle
import sys
import time
from dataclasses import dataclass
from multiprocessing import Pool
from typing import Any

import numpy as np

from lander_autopilot.controllers.base import Demand
from lander_sim.simulation import Simulation
from lander_tools.sweep.case_scene import flown_scene
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import (
    act_on_requests,
    case_controller,
    chute_is_open,
    control_period,
    demand_schedule,
    flight_phase,
    fly_case,
    nominal_scene,
    powered_optimum,
)
from lander_tools.sweep.metrics import BandSample, HoverHold, altitude_and_tilt, band_entry_fuel
from lander_tools.sweep.spec import SweepSpec, load_spec

BEFORE_BRAKING = ("entry", "parachute")  # phases a snapshot may be taken in


@dataclass
class Replayed:
    """One flight's end (SI units; NaN where it never got there)."""

    index: int
    outcome: str  # "band" (reached the band at rest after the powered descent; with --hold: "held" or
    #               "not held" after it), "down", "timeout", "diverged", "no snapshot"
    fuel_ratio: float = math.nan  # fuel from the powered descent's start to the band at rest / the optimum
    optimum: float = math.nan  # [kg] minimum fuel from the handover state (powered_optimum)
    fuel_ratio_balanced: float = math.nan  # the same fuel over the optimum at the thrust with no torque
    #: fuel_ratio with the fuel at the band's entry found within its control period (band_entry_fuel):
    #: a diagnostic, lenient against an optimum at rest at the demand (module docstring of metrics)
    fuel_ratio_entry: float = math.nan
    #: with --like: that entry's fuel over the optimum to the same tolerance (end.hover_band and
    #: end.hover_speed): the two ends alike
    fuel_ratio_like: float = math.nan
    hover_error: float = math.nan  # [m] altitude error where the `hover` phase began
    hover_climb: float = math.nan  # [m/s] climb rate there
    hover_drift: float = math.nan  # [m/s] ground speed there
    band_time: float = math.nan  # [s] from the powered descent's start to the band at rest


#: Design constants: set once as a law is built (designed gains, the braking's margins, the MPC's
#: settings), never learnt in flight, so taken from the current code on replay: a snapshot pickles
#: the margins of the code that made it, and kept they would be replayed under the current code's
#: names, measuring another law than the one in the tree.
_DESIGN = ("K", "k_i", "k_p", "brake_fraction", "stop_above", "target_above", "settings")


def _fill_missing(old: Any, fresh: Any, depth: int = 3) -> None:
    """Give ``old`` (unpickled from older code) the attributes ``fresh`` has and it lacks, and
    fresh's design constants (:data:`_DESIGN`: a change of poles or of a margin is then replayed),
    recursively into attributes that are objects of the same class."""
    if depth < 0 or not hasattr(old, "__dict__") or type(old) is not type(fresh):
        return
    mine = vars(old)
    frozen = getattr(getattr(old, "__dataclass_params__", None), "frozen", False)  # a design record
    for k, v in vars(fresh).items():
        if k not in mine:
            object.__setattr__(old, k, v)  # a field added since: a frozen record's too
        elif k in _DESIGN and not frozen:
            setattr(old, k, v)
        else:
            _fill_missing(mine[k], v, depth - 1)


def _optimum(sim: Simulation, handover: tuple[np.ndarray, np.ndarray, float, bool], altitude: float, cache: str,
             balanced: bool = False, end: tuple[float, float] | None = None) -> float:
    """:func:`powered_optimum`, cached on disk by the handover state (a solve takes 1-4 s) in a folder per
    altitude (and per thrust bound: ``balanced``, the thrust with no torque; and per end: ``end`` =
    (band [m], speed [m/s]) of the hover's tolerance, else at rest at the demand)."""
    key = hashlib.sha1(b"".join(np.asarray(x, float).tobytes() for x in handover[:3]) + bytes([handover[3]])).hexdigest()
    cache = os.path.join(cache, f"{altitude!r}" + ("-balanced" if balanced else "")
                         + (f"-end{end[0]!r}-{end[1]!r}" if end is not None else ""))
    path = os.path.join(cache, key)
    if os.path.exists(path):
        with open(path) as f:
            return float(f.read())
    band, speed = end if end is not None else (0.0, 0.0)
    value = powered_optimum(sim, handover, altitude, balanced=balanced, end_band=band, end_speed=speed)
    os.makedirs(cache, exist_ok=True)
    with open(path, "w") as f:
        f.write(repr(value))
    return value


def _fly(spec: SweepSpec, sim: Simulation, ctrl: Any, k0: int, index: int, folder: str,
         snapshot_altitude: float | None, hold: bool = False, like: bool = False) -> Replayed:
    """From control instant ``k0`` to the band at rest after the powered descent (fly_case's loop);
    with ``snapshot_altitude``, pickles ``(k, sim, ctrl)`` at the first instant under it; with
    ``hold``, on until the hover is held (:class:`HoverHold`, the sweep's success) or the flight ends."""
    scene0 = nominal_scene(spec)
    h_before, h_after, t_change = demand_schedule(spec, scene0, draw_case(spec, index, scene0.vehicle.n_thrusters))
    before, after = Demand(altitude=h_before), Demand(altitude=h_after)
    n_sub, period = control_period(spec, sim.dt)
    n_ctrl = int(math.floor(spec.end.duration / period + 1e-9))
    handover: tuple[np.ndarray, np.ndarray, float, bool] | None = None
    t_powered = math.nan
    row = Replayed(index, "timeout")
    held = HoverHold(spec.end.hover_hold, spec.end.hover_band, spec.end.hover_speed)
    band_before: BandSample | None = None  # the control instant before, from the handover on
    for k in range(k0, n_ctrl + 1):
        st = sim.state()
        t = k * period
        if not np.all(np.isfinite(st.r_W)):
            row.outcome = "diverged"
            return row
        h, _tilt = altitude_and_tilt(st.r_W, st.q)
        err = h - (h_after if t >= t_change else h_before)
        now = BandSample(err, math.sqrt(float(st.v_W @ st.v_W)), float(st.fuel))
        if handover is not None:
            if math.isnan(row.hover_error) and ctrl.phase.value == "hover":
                up = st.r_W / float(np.linalg.norm(st.r_W))
                climb = float(st.v_W @ up)
                row.hover_error, row.hover_climb = err, climb
                row.hover_drift = float(np.linalg.norm(st.v_W - climb * up))
            if row.outcome != "band" and now.within(spec.end.hover_band, spec.end.hover_speed):
                cache = os.path.join(folder, "optimum")
                used = handover[2] - now.fuel  # at the control instant, as the sweep's fuel_ratio
                row.optimum = _optimum(sim, handover, h_after, cache)
                row.fuel_ratio = used / row.optimum
                entry = band_entry_fuel(band_before, now, spec.end.hover_band, spec.end.hover_speed)
                row.fuel_ratio_entry = (handover[2] - entry) / row.optimum
                if like:
                    end = (spec.end.hover_band, spec.end.hover_speed)
                    row.fuel_ratio_like = (handover[2] - entry) / _optimum(sim, handover, h_after, cache, end=end)
                row.fuel_ratio_balanced = used / _optimum(sim, handover, h_after, cache, balanced=True)
                row.band_time, row.outcome = t - t_powered, "band"
                if not hold:
                    return row
            band_before = now
        if flight_phase(sim) != "FLYING":
            row.outcome = "down"
            return row
        if hold and held.update(t, err, now.speed):
            row.outcome = "held"
            return row
        if snapshot_altitude is not None and h < snapshot_altitude and ctrl.phase.value in BEFORE_BRAKING:
            with open(os.path.join(folder, f"{index}.pkl"), "wb") as f:
                pickle.dump((k, sim, ctrl), f)
            snapshot_altitude = None
        out = ctrl.update(t, st, after if t >= t_change else before)
        if out.mode == "powered-descent" and handover is None:
            if snapshot_altitude is not None:
                row.outcome = "no snapshot"  # braking began above the snapshot altitude
                return row
            handover, t_powered = (st.r_W.copy(), st.v_W.copy(), float(st.fuel), chute_is_open(sim)), t
            band_before = now
        act_on_requests(sim, out)
        sim.set_throttles(out.throttles)
        sim.step(n_sub)
    if row.outcome == "band":
        row.outcome = "not held"
    return row


def _task(args: tuple[str, str, int, str, float | None, bool, bool]) -> Replayed:
    spec_path, label, index, folder, altitude, hold, like = args
    spec = load_spec(spec_path)
    ci = [ch.label for ch in spec.controllers].index(label)
    scene0 = nominal_scene(spec)
    fresh = case_controller(spec, ci, scene0.vehicle)
    fresh.reset()
    if altitude is not None:  # make
        sim = Simulation(flown_scene(spec, draw_case(spec, index, scene0.vehicle.n_thrusters)))
        return _fly(spec, sim, fresh, 0, index, folder, altitude, hold, like)
    path = os.path.join(folder, f"{index}.pkl")
    if not os.path.exists(path):
        return Replayed(index, "no snapshot")
    with open(path, "rb") as f:
        k0, sim, ctrl = pickle.load(f)
    _fill_missing(ctrl, fresh)
    return _fly(spec, sim, ctrl, k0, index, folder, None, hold, like)


def _check(args: tuple[str, str, int]) -> tuple[int, float]:
    spec_path, label, index = args
    spec = load_spec(spec_path)
    ci = [ch.label for ch in spec.controllers].index(label)
    return index, float(fly_case(spec, ci, index).row["fuel_ratio"])


def summary(rows: list[Replayed], worst: int) -> str:
    outcomes = {o: sum(r.outcome == o for r in rows) for o in sorted({r.outcome for r in rows})}
    lines = [f"{len(rows)} flights: " + ", ".join(f"{n} {o}" for o, n in outcomes.items())]
    for name in ("fuel_ratio", "fuel_ratio_balanced", "fuel_ratio_entry", "fuel_ratio_like"):
        ratios = np.array([getattr(r, name) for r in rows])
        ok = np.isfinite(ratios)
        if ok.any():
            x = ratios[ok]
            p5, p50, p95 = np.percentile(x, [5, 50, 95])
            lines.append(f"{name} [x optimum] p5 / p50 / p95 / max: {p5:.4f} / {p50:.4f} / {p95:.4f} / {x.max():.4f}, "
                         f"mean {x.mean():.4f}; within 1.03 / 1.05 / 1.10: {(x <= 1.03).sum()} / {(x <= 1.05).sum()} / "
                         f"{(x <= 1.10).sum()} of {ok.sum()}")
    lines.append("worst: case, fuel_ratio (balanced), then where the hover began: altitude error [m], climb [m/s], "
                 "ground speed [m/s]")
    for r in sorted((r for r in rows if np.isfinite(r.fuel_ratio)), key=lambda r: -r.fuel_ratio)[:worst]:
        where = ("(in the band at rest before the phase began)" if math.isnan(r.hover_error)
                 else f"{r.hover_error:+6.2f}  {r.hover_climb:+5.2f}  {r.hover_drift:4.2f}")
        lines.append(f"  {r.index:4d}  {r.fuel_ratio:.4f} ({r.fuel_ratio_balanced:.4f})  {where}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=("make", "replay"))
    ap.add_argument("spec", help="the de-orbit sweep's spec (YAML)")
    ap.add_argument("--controller", default="scheduled", help="the spec's controller label (default: scheduled)")
    ap.add_argument("--folder", help="snapshots (default out/replay/<spec name>/<label>)")
    ap.add_argument("--cases", help="comma-separated case indices (default: all the spec's flights)")
    ap.add_argument("--altitude", type=float, default=2500.0, help="make: snapshot under this altitude [m]")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--worst", type=int, default=10, help="worst flights listed")
    ap.add_argument("--hold", action="store_true", help="fly on until the hover is held (the sweep's success)")
    ap.add_argument("--like", action="store_true",
                    help="also fuel_ratio_like: the band's entry over the optimum to the hover's tolerance "
                         "(one more convex solve a flight, cached)")
    ap.add_argument("--check", type=int, default=0, metavar="K", help="re-fly the first K cases whole (fly_case) and compare")
    ap.add_argument("--csv", help="write one row a flight here")
    a = ap.parse_args(argv)
    spec = load_spec(a.spec)
    labels = [ch.label for ch in spec.controllers]
    if a.controller not in labels:
        ap.error(f"--controller: {a.controller!r} is not one of the spec's {labels}")
    folder = a.folder or os.path.join("out", "replay", spec.name, a.controller)
    os.makedirs(folder, exist_ok=True)
    cases = [int(x) for x in a.cases.split(",")] if a.cases else list(range(spec.flights))
    altitude = a.altitude if a.mode == "make" else None
    t0 = time.perf_counter()
    with Pool(a.workers) as pool:
        rows = pool.map(_task, [(a.spec, a.controller, i, folder, altitude, a.hold, a.like) for i in cases], chunksize=1)
    print(f"{a.mode}: {spec.name} / {a.controller}, {time.perf_counter() - t0:.0f} s wall on {a.workers} workers")
    print(summary(rows, a.worst))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["index", "outcome", "fuel_ratio", "optimum", "fuel_ratio_balanced", "hover_error", "hover_climb",
                        "hover_drift", "band_time", "fuel_ratio_entry", "fuel_ratio_like"])
            for r in rows:
                w.writerow([r.index, r.outcome, r.fuel_ratio, r.optimum, r.fuel_ratio_balanced, r.hover_error, r.hover_climb,
                            r.hover_drift, r.band_time, r.fuel_ratio_entry, r.fuel_ratio_like])
    bad = 0
    if a.check:
        with Pool(a.workers) as pool:
            whole = dict(pool.map(_check, [(a.spec, a.controller, i) for i in cases[:a.check]], chunksize=1))
        by_index = {r.index: r for r in rows}
        for i, ratio in whole.items():
            same = ratio == by_index[i].fuel_ratio or (math.isnan(ratio) and math.isnan(by_index[i].fuel_ratio))
            bad += not same
            print(f"check case {i}: whole flight {ratio!r}, here {by_index[i].fuel_ratio!r}: {'same' if same else 'DIFFERENT'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
