"""Shared plumbing of the benchmarks: arguments, plain-text tables, JSON and PNG output, problems."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # `python bench/NAME.py` from a source checkout
    sys.path.insert(0, str(ROOT))

from lander_sim.integrators.base import derivative  # noqa: E402
from lander_sim.physics.dynamics import LanderDynamics  # noqa: E402
from lander_sim.physics.models import Inputs, InverseSquareGravity  # noqa: E402
from lander_sim.physics.vehicle import Vehicle  # noqa: E402
from lander_sim.simulation import Simulation  # noqa: E402

FIXED = ("symplectic-euler", "verlet", "geometric", "rk4")


def parser(description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--json", metavar="FILE", help="also write the figures machine-readable to FILE")
    p.add_argument("--out", metavar="DIR", default=None, help="directory for PNG plots (default: none)")
    p.add_argument("--quick", action="store_true", help="small version (< 60 s), for tests and smoke runs")
    return p


def table(title: str, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A plain-text table; floats in %.3g."""
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return "-" if math.isnan(v) else f"{v:.3g}"
        return str(v)
    body = [[cell(v) for v in r] for r in rows]
    w = [max(len(h), *(len(r[i]) for r in body)) if body else len(h) for i, h in enumerate(header)]
    line = "  ".join(h.ljust(w[i]) for i, h in enumerate(header))
    out = [title, line, "-" * len(line)]
    out += ["  ".join(r[i].rjust(w[i]) for i in range(len(header))) for r in body]
    return "\n".join(out) + "\n"


def write_json(path: str | None, data: dict[str, Any]) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(data, indent=1, default=float))


def pyplot():
    """matplotlib.pyplot with the non-interactive backend."""
    from lander_tools.plotstyle import pyplot as _pyplot

    return _pyplot()


def write_outputs(args: argparse.Namespace, data: dict[str, Any], plot: Callable[[dict[str, Any]], Any], png: str) -> int:
    """The end of every benchmark: ``data`` as JSON to ``--json``, ``plot(data)`` (a matplotlib
    Figure drawn from that same JSON) to ``--out``/``png``; returns the exit status 0."""
    write_json(args.json, data)
    if args.out:
        from lander_tools.plotstyle import save

        save(plot(data), Path(args.out) / png, dpi=90)
    return 0


def timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


# --- problems built from the core -------------------------------------------------


def free_top(inertia: tuple[float, float, float]) -> LanderDynamics:
    """Torque-free rigid body about a fixed centre (no models): eq 2 with Q = 0."""
    v = Vehicle(dry_mass=1.0, fuel_capacity=0.0, inertia_diag=inertia)
    return LanderDynamics(v, [], "quaternion", False, Inputs(throttles=np.zeros(0)))


def point_orbit(gm: float) -> LanderDynamics:
    """A point-like body (unit inertia) under inverse-square gravity only."""
    v = Vehicle(dry_mass=1.0, fuel_capacity=0.0, inertia_diag=(1.0, 1.0, 1.0))
    return LanderDynamics(v, [InverseSquareGravity(gm=gm)], "quaternion", True, Inputs(throttles=np.zeros(0)))


def scene_dynamics(name: str, throttles: Sequence[float] | None = None, wind: Sequence[float] | None = None):
    """(dynamics, initial y) of a packaged scene, with optional fixed throttles and wind."""
    from lander_sim.scenes import load_scene

    sim = Simulation(load_scene(name))
    if throttles is not None:
        sim.set_throttles(throttles)
    if wind is not None:
        sim.set_wind(wind)
    return sim.dynamics, sim.y.copy()


def run_fixed(integ, dyn, y0: np.ndarray, dt: float, n: int) -> tuple[np.ndarray, float, int]:
    """n steps from y0; returns (final y, wall time [s], derivative evaluations)."""
    y = y0.copy()
    e0 = dyn.evaluations
    t0 = time.perf_counter()
    for i in range(n):
        integ.step(dyn, i * dt, y, dt)
    return y, time.perf_counter() - t0, dyn.evaluations - e0


def run_scipy(method: str, dyn, y0: np.ndarray, T: float, rtol: float, atol: float) -> tuple[np.ndarray, float, int]:
    """scipy.integrate.solve_ivp on the same first-order form (integrators.base.derivative)."""
    from scipy.integrate import solve_ivp

    acc = np.zeros(6)

    def f(t: float, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        derivative(dyn, t, y, out, acc)
        return out

    e0 = dyn.evaluations
    t0 = time.perf_counter()
    sol = solve_ivp(f, (0.0, T), y0.copy(), method=method, rtol=rtol, atol=atol)
    return sol.y[:, -1].copy(), time.perf_counter() - t0, dyn.evaluations - e0
