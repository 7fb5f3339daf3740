"""Navigation filter consistency: a Monte Carlo of core flights per scene, NEES and NIS against chi-square.

For each case, ``runs`` flights (seeds 0 .. runs-1: sensor noise and biases, and the initial
estimation error drawn from the filter's initial covariance) of the scene flown by its own
autopilot on the truth, with the error-state EKF (lander_autopilot/estimation) alongside:

* ``anees``: NEES averaged over runs and times, with the 95 % interval of one time's run-average
  (``dof`` 15); ``nees_frac_inside``: the fraction of times whose run-average lies inside it;
* ``anis_<sensor>``: NIS averaged over every update of the sensor in every run, with its exact 95 %
  interval (innovations of a consistent filter are white);
* ``err_p50`` / ``err_p95`` per error-state component: percentiles of ``|truth - estimate|`` over all
  runs and the times after the first ``settle`` seconds.

Cases: ``landing`` (landing-hover, the landing law, 30 s of the descent from 500 m; IMU, star
tracker, radar altimeter, Doppler), ``hover`` (hover-canted, the combined law righting a tilted,
rolling start, 60 s; the same sensors: the star tracker drops out while the body rate exceeds
2 deg/s), ``orbit`` (circular-orbit, coasting, 300 s; IMU, star tracker, ground fix, initial errors
of 1 km, 1 m/s and 1 degree).

A scene file of your own that switches sensors on (``sensors:``, with ``imu``) is flown the same way:

    python bench/nav_consistency.py [--runs N] [--case NAME] [--json FILE] [--quick]
    python bench/nav_consistency.py --scene FILE.yaml --duration S [--runs N]
"""
from __future__ import annotations

import dataclasses
import sys
import time

import _common as C
import numpy as np

from lander_autopilot.estimation.consistency import anees, anis
from lander_autopilot.estimation.ekf import N_ERR
from lander_autopilot.estimation.flights import INITIAL_SIGMA, fly
from lander_sim.scenes import load_scene
from lander_sim.sensors.params import defaults
from lander_sim.sensors.suite import SENSORS, SensorsConfig

ERR_NAMES = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z", "th_x", "th_y", "th_z",
             "bg_x", "bg_y", "bg_z", "ba_x", "ba_y", "ba_z")
DESCENT = ("imu", "star_tracker", "altimeter", "doppler")
CASES = {
    # name: (scene, sensors, duration [s], initial sigma (m, m/s, rad), settle [s])
    "landing": ("landing-hover", DESCENT, 30.0, INITIAL_SIGMA, 5.0),
    "hover": ("hover-canted", DESCENT, 60.0, INITIAL_SIGMA, 5.0),
    "orbit": ("circular-orbit", ("imu", "star_tracker", "ground_fix"), 300.0, (1000.0, 1.0, np.radians(1.0)), 0.0),
}


def run_case(name: str, runs: int, scene_file: str | None = None, duration_s: float = 60.0) -> dict:
    if scene_file is not None:
        sc = load_scene(scene_file)
        if sc.sensors is None:
            raise SystemExit(f"{scene_file}: the scene switches no sensors on (add a sensors: section with imu)")
        scene_name, keys, duration, sigma0, settle = sc.name, tuple(sc.sensors.sections), duration_s, INITIAL_SIGMA, 5.0
    else:
        scene_name, keys, duration, sigma0, settle = CASES[name]
        sc = load_scene(scene_name)
        sc = dataclasses.replace(sc, sensors=SensorsConfig(0, {k: defaults(SENSORS[k][0]) for k in keys}))
    t0 = time.perf_counter()
    recs = [fly(sc, seed, duration, initial_sigma=sigma0) for seed in range(runs)]
    wall = time.perf_counter() - t0
    K = min(len(r.nees) for r in recs)
    check, frac = anees(np.array([r.nees[:K] for r in recs]), N_ERR)
    out: dict = {"case": name, "scene": scene_name, "sensors": list(keys), "runs": runs, "duration_s": duration,
                 "steps": K, "wall_s": wall, "ends": sorted({r.end for r in recs}),
                 "anees": check.value, "anees_bounds": list(check.bounds), "anees_inside": check.inside,
                 "nees_frac_inside": frac}
    for key in sorted(recs[0].nis):
        vals = np.array([n for r in recs for n, _ in r.nis.get(key, [])])
        c = anis(vals, recs[0].nis[key][0][1])
        out[f"anis_{key}"] = {"value": c.value, "dof": c.dof, "bounds": list(c.bounds), "inside": c.inside,
                              "updates": int(vals.size)}
    t = np.array(recs[0].t[:K])
    E = np.abs(np.array([np.array(r.errors[:K]) for r in recs]))[:, t >= settle, :].reshape(-1, N_ERR)
    out["err_p50"] = dict(zip(ERR_NAMES, np.percentile(E, 50, axis=0).tolist()))
    out["err_p95"] = dict(zip(ERR_NAMES, np.percentile(E, 95, axis=0).tolist()))
    return out


def main(argv: list[str] | None = None) -> int:
    p = C.parser(__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=100, help="flights per case (default 100)")
    p.add_argument("--case", choices=sorted(CASES), action="append", help="only these cases (default: all)")
    p.add_argument("--scene", metavar="FILE", help="fly this scene file (its own sensors) instead of the cases")
    p.add_argument("--duration", type=float, default=60.0, help="flight time with --scene [s] (default 60)")
    args = p.parse_args(argv)
    runs = 10 if args.quick else args.runs
    if args.scene:
        results = [run_case("scene", runs, args.scene, args.duration)]
    else:
        results = [run_case(n, runs) for n in (args.case or list(CASES))]
    rows = []
    for r in results:
        nis = "; ".join(f"{k[5:]} {v['value']:.3f} [{v['bounds'][0]:.3f}, {v['bounds'][1]:.3f}]"
                        for k, v in r.items() if k.startswith("anis_"))
        rows.append([r["case"], r["runs"], f"{r['anees']:.2f} [{r['anees_bounds'][0]:.2f}, {r['anees_bounds'][1]:.2f}]",
                     f"{r['nees_frac_inside']:.2f}", nis, f"{r['wall_s']:.0f}"])
    print(C.table("filter consistency (NEES dof 15; 95 % intervals)",
                  ["case", "runs", "ANEES [95 %]", "times inside", "ANIS per sensor [95 %]", "wall s"], rows))
    for r in results:
        print(C.table(f"{r['case']}: |error| percentiles over runs and times",
                      ["state", "p50", "p95"], [[k, r["err_p50"][k], r["err_p95"][k]] for k in ERR_NAMES]))
    C.write_json(args.json, {"cases": results})
    return 0


if __name__ == "__main__":
    sys.exit(main())
