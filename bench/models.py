"""Cost of the models: steps per second of each scene, and of the lander with models added one by one.

Velocity Verlet on the numpy Dynamics path (two evaluations per step), one core.

    python bench/models.py [--json FILE] [--out DIR] [--quick]
"""
from __future__ import annotations

import sys
import time

import _common as C
import numpy as np

from lander_sim.integrators import make
from lander_sim.physics.dynamics import LanderDynamics
from lander_sim.physics.models import (
    Atmosphere,
    Inputs,
    InverseSquareGravity,
    MeshDrag,
    Parachute,
    SphereDrag,
    Thrusters,
    sphere_mesh,
)
from lander_sim.physics.models.parachute import ChuteStatus
from lander_sim.scenes import list_scenes, load_scene
from lander_sim.simulation import Phase, Simulation


def _rate(step, n: int, repeats: int = 3) -> float:
    """Best of ``repeats`` timings of ``n`` steps (the machine is shared: the best is the least disturbed)."""
    step(10)  # warm-up
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        done = step(n)
        best = max(best, (done if done is not None else n) / (time.perf_counter() - t0))
    return best


def scenes(quick: bool) -> list[dict]:
    n = 300 if quick else 2000
    rows = []
    for info in list_scenes():
        sc = load_scene(info.name)
        sim = Simulation(sc)

        def step(m: int, sim=sim) -> int:
            # Count flying steps only: after touchdown a step costs nothing.
            if sim.phase is not Phase.FLYING:
                sim.reset()
            for k in range(m):
                if sim.phase is not Phase.FLYING:
                    return k
                sim.step()
            return m
        rows.append(dict(scene=info.name, integrator=sc.integrator, attitude=sc.attitude,
                         models=", ".join(sc.models.configs) or "(none)",
                         steps_per_s=_rate(step, n)))
    return rows


def one_by_one(quick: bool) -> list[dict]:
    n = 500 if quick else 5000
    sc = load_scene("hover")
    veh = sc.vehicle
    inputs = Inputs(throttles=np.full(4, 0.5), wind_W=np.array([3.0, 0.0, 1.0]))
    chute = Parachute()
    chute.status = ChuteStatus.DEPLOYED
    c_B, n_B, areas = sphere_mesh(1.0, np.zeros(3), 12, 24)
    stages = [
        ("rotation only (Euler eq 2)", [], False),
        ("+ inverse-square gravity", [InverseSquareGravity()], False),
        ("+ atmosphere + sphere drag", [InverseSquareGravity(), SphereDrag()], True),
        ("+ 4 thrusters, fuel burn", [InverseSquareGravity(), SphereDrag(), Thrusters(veh)], True),
        ("+ parachute (deployed)", [InverseSquareGravity(), SphereDrag(), chute, Thrusters(veh)], True),
        ("mesh drag (12x24 panels) instead of sphere", [InverseSquareGravity(), MeshDrag(c_B, n_B, areas), Thrusters(veh)], True),
    ]
    steppers = []
    for label, models, atmo in stages:
        dyn = LanderDynamics(veh, models, "quaternion", True, inputs, Atmosphere() if atmo else None, 3386e3)
        y = sc.initial_state.copy()
        integ = make("verlet")

        def step(m: int, dyn=dyn, y=y, integ=integ) -> None:
            for k in range(m):
                integ.step(dyn, k * 0.01, y, 0.01)
        steppers.append((label, step))
    # Round-robin repeats: a burst of load from other processes then hits every stage alike.
    best = {label: 0.0 for label, _ in steppers}
    for _ in range(5):
        for label, step in steppers:
            best[label] = max(best[label], _rate(step, n, repeats=1))
    rows = [dict(models=label, steps_per_s=best[label]) for label, _ in steppers]
    base = rows[0]["steps_per_s"]
    for r in rows:
        r["relative_cost"] = base / r["steps_per_s"]
    return rows


def plot(data: dict) -> object:
    """Bar chart of steps per second as models are switched on one by one (``data``: this benchmark's JSON)."""
    plt = C.pyplot()
    ob = data["one_by_one"]
    fig, ax = plt.subplots(figsize=(7, 3.2), layout="constrained")
    ax.barh([r["models"] for r in ob][::-1], [r["steps_per_s"] for r in ob][::-1])
    ax.set_xlabel("Verlet steps per second [1/s] (numpy path, one core)")
    ax.set_ylabel("models switched on")
    return fig


def main(argv: list[str] | None = None) -> int:
    args = C.parser(__doc__.splitlines()[0]).parse_args(argv)
    sc = scenes(args.quick)
    print(C.table("steps per second of each scene (its own integrator, Simulation.step, numpy path)",
                  ["scene", "integrator", "attitude", "models on", "steps/s"],
                  [[r["scene"], r["integrator"], r["attitude"], r["models"], f"{r['steps_per_s']:.0f}"] for r in sc]))
    ob = one_by_one(args.quick)
    print(C.table("lander, Verlet, models switched on one by one", ["models", "steps/s", "cost x"],
                  [[r["models"], f"{r['steps_per_s']:.0f}", r["relative_cost"]] for r in ob]))
    return C.write_outputs(args, {"scenes": sc, "one_by_one": ob}, plot, "bench-models.png")


if __name__ == "__main__":
    sys.exit(main())
