"""Closed loop speed: the Python loop against the compiled loop, and the two sweep paths, in one run.

* ``python_loops_per_s``: one flight of ``hover-canted`` with the ``combined`` law, core-only, in
  Python: every 0.1 s ``Simulation.state()`` -> ``controller.update()`` -> ``set_throttles()`` ->
  ``step()`` (the compiled Verlet kernel does the physics).
* ``compiled_loops_per_s``: the same flight in the compiled closed loop
  (:func:`lander_tools.sweep.batched.fly_compiled`, one thread), timed over ``copies`` flights in
  one call after the set-up; ``trajectory_rel_diff`` is the largest difference of the two loops'
  states at the control instants, relative to each part's size (position, velocity, quaternion,
  body rate, fuel).
* ``truth_loops_per_s``, ``estimate_loops_per_s``, ``estimate_compiled_loops_per_s``: the same
  flight with the sensors of ``landing-sensors`` (IMU, star tracker, altimeter, Doppler) switched
  on, the law flown on the truth, and on the navigation filter's estimate
  (:class:`lander_autopilot.estimation.onboard.Onboard`: sensors sampled every step, the filter fed
  a tick at a time) with the Python filter and with the compiled one, in turn in this run (the
  loop itself is Python); ``estimate_filter_share``, ``estimate_compiled_filter_share``: the
  fraction of each one's time in the filter (``TickFeeder.advance``: propagation and updates).
* ``estimate_batched_loops_per_s``: that flight on the estimate in the compiled loop of the batched
  core (:func:`lander_tools.sweep.batched.fly_compiled` with ``navigation``: the sensors and the
  filter inside the loop, one thread), timed over ``copies`` flights in one call after the set-up.
* ``estimate_per_flight_flights_per_s`` and ``estimate_batched_flights_per_s``: a sweep on the
  estimate (``sweeps/compare-nav-hover.yaml``'s law on the estimate alone: 60-s hovers of
  ``combined-quaternion`` with the sensors of ``landing-hover-sensors``) on the per-flight and the
  batched path, 2 local workers, wall time after start-up; ``estimate_summary_equal`` says whether
  the summaries of the same flights on both paths print alike.
* ``ceiling_loops_per_s``, ``loop_over_ceiling``: bench/ceiling_loop.py's fused loop of the same
  flight (written only to be fast, bit for bit the same samples: ``ceiling_vs_loop_max_rel``) and
  the compiled loop as a fraction of it, the two alternating in this run.
* ``per_flight_flights_per_s`` and ``batched_flights_per_s``: ``sweeps/hover-robustness.yaml`` on
  the per-flight and the batched path (:func:`lander_tools.sweep.runner.run_local`, 2 workers),
  wall time of the run after start-up; ``summary_equal`` says whether the two summaries print alike.
  ``batched_1_worker_cpu_s``: CPU seconds of the batched sweep flown in this process (set-up of
  each flight included), the figure that does not depend on what else the machine is doing.
* ``setup_ms_per_flight`` and ``reference_setup_ms_per_flight``: CPU milliseconds to set one
  flight up for the batched core, the fast way (values derived from the nominal scene's
  Simulation, :class:`lander_tools.sweep.batched.SetupTemplate`) and by building the flight's scene and
  Simulation; ``load_average_1min_end``: the load when the run ended.

Timings are noisy on a shared machine: compare the ratios within one run and say the load.

    python bench/closed_loop.py [--json FILE] [--quick]
"""
from __future__ import annotations

import dataclasses
import os
import sys
import time

import _common as C
import ceiling_loop
import numpy as np

from lander_autopilot.controllers import Demand, make_controller
from lander_autopilot.controllers.compiled import compiled_form
from lander_autopilot.estimation.onboard import Onboard
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.sweep import batched, summary
from lander_tools.sweep import batched_kernel as bk
from lander_tools.sweep.runner import run_local
from lander_tools.sweep.spec import load_spec

SCENE, LAW, DURATION = "hover-canted", "combined", 60.0
PARTS = {"position": slice(0, 3), "velocity": slice(3, 6), "quaternion": slice(6, 10), "body rate": slice(10, 13),
         "fuel": slice(13, 14)}


def python_loop(repeats: int) -> tuple[float, np.ndarray]:
    """Loops per second of the Python closed loop and the states of its last flight (601, 14)."""
    scene = load_scene(SCENE)
    ctrl = make_controller(LAW, scene.vehicle)
    demand = Demand()
    n = int(round(DURATION / scene.dt))
    best = float("inf")
    for _ in range(repeats):
        sim = Simulation(scene)
        ctrl.reset()
        states = np.empty((n + 1, 14))
        t0 = time.perf_counter()
        for k in range(n):
            states[k] = sim.y
            out = ctrl.update(sim.t, sim.state(), demand)
            sim.set_throttles(out.throttles)
            sim.step()
        best = min(best, time.perf_counter() - t0)
        states[n] = sim.y
    return n / best, states


def sensor_scene():
    """``SCENE`` with the sensors of ``landing-sensors`` switched on (the flight itself is the same)."""
    scene = load_scene(SCENE)
    sensors = load_scene("landing-sensors").sensors
    return dataclasses.replace(scene, name=f"{SCENE}-sensors", sensors=dataclasses.replace(sensors, seed=1))


def estimate_loop(repeats: int) -> dict[str, float]:
    """Loops per second of the Python closed loop on the truth, on the estimate with the Python filter
    and on the estimate with the compiled filter (in turn, best of ``repeats`` each), and the share of
    each estimate loop's time in the filter."""
    scene = sensor_scene()
    ctrl = make_controller(LAW, scene.vehicle)
    demand = Demand()
    n = int(round(DURATION / scene.dt))
    best = {"truth": float("inf"), "python": float("inf"), "compiled": float("inf")}
    share = {"python": 0.0, "compiled": 0.0}
    for _ in range(repeats):
        for nav in best:
            sim = Simulation(scene)
            ctrl.reset()
            t0 = time.perf_counter()
            if nav == "truth":
                for _ in range(n):
                    sim.set_throttles(ctrl.update(sim.t, sim.state(), demand).throttles)
                    sim.step()
                best[nav] = min(best[nav], time.perf_counter() - t0)
                continue
            onboard = Onboard(sim, scene.sensors, compiled=nav == "compiled")
            t0 = time.perf_counter()
            in_filter = 0.0
            for _ in range(n):
                f0 = time.perf_counter()
                state = onboard.state()
                in_filter += time.perf_counter() - f0
                sim.set_throttles(ctrl.update(sim.t, state, demand).throttles)
                onboard.step()
            wall = time.perf_counter() - t0
            if wall < best[nav]:
                best[nav], share[nav] = wall, in_filter / wall
    return {"truth_loops_per_s": n / best["truth"], "estimate_loops_per_s": n / best["python"],
            "estimate_compiled_loops_per_s": n / best["compiled"], "estimate_filter_share": share["python"],
            "estimate_compiled_filter_share": share["compiled"]}


def estimate_batched_loop(copies: int, repeats: int) -> float:
    """Loops per second of the compiled loop on the estimate (sensors and filter inside, one thread)."""
    scene = sensor_scene()
    law = compiled_form(make_controller(LAW, scene.vehicle))
    sim = Simulation(scene)
    best = float("inf")
    n = int(round(DURATION / scene.dt))
    batched.fly_compiled(sim, law, Demand().altitude, DURATION, navigation=True)  # load the compiled loop
    for _ in range(repeats):
        t0 = time.perf_counter()
        batched.fly_compiled(sim, law, Demand().altitude, DURATION, copies=copies, navigation=True)
        best = min(best, time.perf_counter() - t0)
    return copies * n / best


def estimate_sweep(flights_per_flight: int, flights_batched: int, workers: int) -> dict[str, float]:
    """Flights per second of a sweep on the estimate on both paths (module docstring)."""
    full = load_spec(C.ROOT / "sweeps" / "compare-nav-hover.yaml")
    spec = dataclasses.replace(full, controllers=[c for c in full.controllers if c.navigation == "estimate"])
    run_local(dataclasses.replace(spec, flights=2), workers=1, progress=False, path="batched")  # load the compiled loop
    small = dataclasses.replace(spec, flights=flights_per_flight)
    pf = run_local(small, workers=workers, progress=False, path="per-flight")
    same = run_local(small, workers=workers, progress=False, path="batched")
    bt = run_local(dataclasses.replace(spec, flights=flights_batched), workers=workers, progress=False, path="batched")
    text = [summary.format_summary(summary.summarise(r.rows, spec.metrics), []) for r in (pf, same)]
    return {"estimate_per_flight_flights": len(pf.rows), "estimate_per_flight_wall_s": pf.wall_time,
            "estimate_per_flight_flights_per_s": pf.flights_per_second, "estimate_batched_flights": len(bt.rows),
            "estimate_batched_wall_s": bt.wall_time, "estimate_batched_flights_per_s": bt.flights_per_second,
            "estimate_batched_path": bt.path_note, "estimate_summary_equal": text[0] == text[1]}


def compiled_loop(copies: int, repeats: int) -> tuple[float, np.ndarray]:
    """Loops per second of the compiled closed loop (one thread) and one flight's states."""
    scene = load_scene(SCENE)
    law = compiled_form(make_controller(LAW, scene.vehicle))
    sim = Simulation(scene)
    states = batched.fly_compiled(sim, law, Demand().altitude, DURATION, record_states=True)["states"][0]
    n = states.shape[0] - 1
    inputs = batched.pack_flights([batched.FlightSetup(-1, batched.FlightCase(-1, 0), sim, (500.0, 500.0, 0.0))] * copies, n)
    params, K = law.pack()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        bk.fly_flights(inputs, params, K, n, 1, scene.dt, scene.dt, sim.ground.contact_radius, parallel=False)
        best = min(best, time.perf_counter() - t0)
    return copies * n / best, states


def sweep_rates(flights_per_flight: int, flights_batched: int, workers: int) -> dict[str, float | str | bool]:
    spec = load_spec(C.ROOT / "sweeps" / "hover-robustness.yaml")
    run_local(dataclasses.replace(spec, flights=4), workers=1, progress=False)  # load the compiled loop (cache)
    small = dataclasses.replace(spec, flights=flights_per_flight)
    pf = run_local(small, workers=workers, progress=False, path="per-flight")
    bt_same = run_local(small, workers=workers, progress=False, path="batched")
    big = dataclasses.replace(spec, flights=flights_batched)
    bt = run_local(big, workers=workers, progress=False, path="batched")
    one, cpu = batched_cpu(big)
    text = [summary.format_summary(summary.summarise(r.rows, spec.metrics), []) for r in (pf, bt_same)]
    return {
        "per_flight_flights": len(pf.rows), "per_flight_wall_s": pf.wall_time, "per_flight_flights_per_s": pf.flights_per_second,
        "batched_flights": len(bt.rows), "batched_wall_s": bt.wall_time, "batched_flights_per_s": bt.flights_per_second,
        "summary_equal": text[0] == text[1], "sweep_workers": workers,
        "batched_1_worker_wall_s": one.wall_time, "batched_1_worker_cpu_s": cpu,
    }


def batched_cpu(spec) -> tuple[object, float]:
    """``spec`` on the batched path with one worker in this process: (its result, CPU seconds),
    the figure that does not depend on what else the machine is doing."""
    cpu0 = time.process_time()
    one = run_local(spec, workers=1, progress=False, path="batched")
    return one, time.process_time() - cpu0


def batched_cpu_rate(flights: int) -> float:
    """Flights per CPU second of ``sweeps/hover-robustness.yaml`` cut to ``flights`` flights on the
    batched path, one worker in this process (set-up of each flight included), after a warm-up
    sweep of 4 flights that loads the compiled loop: the regression guard's figure."""
    spec = load_spec(C.ROOT / "sweeps" / "hover-robustness.yaml")
    run_local(dataclasses.replace(spec, flights=4), workers=1, progress=False, path="batched")
    one, cpu = batched_cpu(dataclasses.replace(spec, flights=flights))
    return len(one.rows) / cpu


def setup_cost(flights: int) -> dict[str, float]:
    """CPU ms per flight of the batched core's set-up: fast, and building scene + Simulation."""
    spec = load_spec(C.ROOT / "sweeps" / "hover-robustness.yaml")
    tpl = batched.template_of(spec)
    out = {}
    for name, make in (("setup_ms_per_flight", lambda i: batched.setup_flight_fast(spec, i, tpl)),
                       ("reference_setup_ms_per_flight", lambda i: batched.setup_flight(spec, i, 4))):
        make(0)
        t0 = time.process_time()
        for i in range(flights):
            make(i)
        out[name] = 1e3 * (time.process_time() - t0) / flights
    return out


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    load = os.getloadavg()[0]
    py_rate, py_states = python_loop(2 if args.quick else 5)
    c_rate, c_states = compiled_loop(50 if args.quick else 500, 3)
    est = estimate_loop(2 if args.quick else 5)
    est["estimate_batched_loops_per_s"] = estimate_batched_loop(20 if args.quick else 100, 3)
    est_sweep = estimate_sweep(10 if args.quick else 40, 100 if args.quick else 400, 2)
    side = ceiling_loop.time_side_by_side(ceiling_loop.flight(), 50 if args.quick else 300, 3 if args.quick else 5)
    diffs = {name: float(np.max(np.abs(c_states[:, s] - py_states[:, s])) / np.max(np.abs(py_states[:, s])))
             for name, s in PARTS.items()}
    sweeps = sweep_rates(50 if args.quick else 200, 200 if args.quick else 1000, 2)
    setup = setup_cost(100 if args.quick else 500)
    data = {
        "scene": SCENE, "controller": LAW, "flight_s": DURATION, "load_average_1min": load,
        "python_loops_per_s": py_rate, "compiled_loops_per_s": c_rate, "loop_speedup": c_rate / py_rate,
        **est, "trajectory_rel_diff": diffs, "ceiling_loops_per_s": side["ceiling_loops_per_s"],
        "loop_over_ceiling": side["loop_over_ceiling"], "ceiling_vs_loop_max_rel": ceiling_loop.agreement(ceiling_loop.flight()),
        **sweeps,
        "sweep_speedup": sweeps["batched_flights_per_s"] / sweeps["per_flight_flights_per_s"],
        **est_sweep,
        "estimate_sweep_speedup": est_sweep["estimate_batched_flights_per_s"] / est_sweep["estimate_per_flight_flights_per_s"],
        **setup, "load_average_1min_end": os.getloadavg()[0],
    }
    print(C.table(f"Closed loop, one flight of {SCENE} with {LAW!r} ({DURATION:g} s at 10 Hz; load {load:.1f} on {os.cpu_count()} cores)",
                  ["loop", "loops/s", "us/loop"],
                  [["Python", py_rate, 1e6 / py_rate], ["compiled (1 thread)", c_rate, 1e6 / c_rate],
                   ["Python, sensors on, on the truth (in turn with the next two)", est["truth_loops_per_s"],
                    1e6 / est["truth_loops_per_s"]],
                   ["Python, on the estimate, Python filter", est["estimate_loops_per_s"], 1e6 / est["estimate_loops_per_s"]],
                   ["Python, on the estimate, compiled filter", est["estimate_compiled_loops_per_s"],
                    1e6 / est["estimate_compiled_loops_per_s"]],
                   ["compiled (1 thread), on the estimate: sensors and filter in the loop", est["estimate_batched_loops_per_s"],
                    1e6 / est["estimate_batched_loops_per_s"]]]))
    print(f"on the estimate, time in the filter (TickFeeder.advance): {100 * est['estimate_filter_share']:.0f} % "
          f"with the Python filter, {100 * est['estimate_compiled_filter_share']:.0f} % with the compiled one\n")
    print(f"compiled loop / ceiling (bench/ceiling_loop.py: the same flight fused, written only to be fast; alternating, "
          f"medians of {side['rounds']}): {data['loop_over_ceiling']:.2f} ({side['compiled_loops_per_s']:.3g} vs "
          f"{data['ceiling_loops_per_s']:.3g} loops/s); ceiling vs loop, max rel. difference {data['ceiling_vs_loop_max_rel']:.3g}\n")
    print(C.table("Compiled vs Python trajectory: max |difference| / max |value| at the control instants",
                  ["part", "relative difference"], [[k, v] for k, v in diffs.items()]))
    print(C.table(f"sweeps/hover-robustness.yaml on {sweeps['sweep_workers']} local workers (wall time after start-up)",
                  ["path", "flights", "wall [s]", "flights/s"],
                  [["per-flight", sweeps["per_flight_flights"], sweeps["per_flight_wall_s"], sweeps["per_flight_flights_per_s"]],
                   ["batched", sweeps["batched_flights"], sweeps["batched_wall_s"], sweeps["batched_flights_per_s"]]]))
    print(C.table(f"A sweep on the estimate (sweeps/compare-nav-hover.yaml, its law on the estimate) on {sweeps['sweep_workers']} "
                  "local workers (wall time after start-up)", ["path", "flights", "wall [s]", "flights/s"],
                  [["per-flight", est_sweep["estimate_per_flight_flights"], est_sweep["estimate_per_flight_wall_s"],
                    est_sweep["estimate_per_flight_flights_per_s"]],
                   [est_sweep["estimate_batched_path"], est_sweep["estimate_batched_flights"], est_sweep["estimate_batched_wall_s"],
                    est_sweep["estimate_batched_flights_per_s"]]]))
    print(f"on the estimate: loop speed-up {est['estimate_batched_loops_per_s'] / est['estimate_compiled_loops_per_s']:.0f}x "
          f"over the Python loop with the compiled filter, sweep speed-up {data['estimate_sweep_speedup']:.0f}x; summaries "
          f"of the same {est_sweep['estimate_per_flight_flights']} flights on both paths "
          f"{'print alike' if est_sweep['estimate_summary_equal'] else 'DIFFER'}")
    print(f"batched, 1 worker in this process: {sweeps['batched_1_worker_wall_s']:.2f} s wall, "
          f"{sweeps['batched_1_worker_cpu_s']:.2f} s CPU for {sweeps['batched_flights']} flights "
          "(CPU time does not depend on other load; on 2 idle cores the 2-worker wall is about half of it)")
    print(f"loop speed-up {data['loop_speedup']:.0f}x, sweep speed-up {data['sweep_speedup']:.0f}x; "
          f"summaries of the same {sweeps['per_flight_flights']} flights on both paths "
          f"{'print alike' if sweeps['summary_equal'] else 'DIFFER'}")
    print(f"set-up of one flight for the batched core: {setup['setup_ms_per_flight']:.3f} ms CPU "
          f"(building its scene and Simulation: {setup['reference_setup_ms_per_flight']:.3f} ms); "
          f"load {load:.1f} at the start, {data['load_average_1min_end']:.1f} at the end")
    C.write_json(args.json, data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
