"""The compiled lander kernel against the numpy Dynamics + Verlet path it replaces."""
from __future__ import annotations

import numpy as np
import pytest

from lander_sim import fast
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation

if not fast.HAVE_NUMBA:  # the kernel still runs as plain Python then, just slowly
    pytestmark = pytest.mark.skip(reason="numba is not importable: the fast path is the slow fallback here")


def _pair(scene: str, throttles, wind, dt: float = 0.01):
    sim = Simulation(load_scene(scene), dt=dt)
    sim.set_throttles(throttles)
    sim.set_wind(wind)
    return sim, fast.FastLander(sim.dynamics)


@pytest.mark.parametrize(
    ("scene", "throttles", "wind"),
    [("hover", [0.6, 0.5, 0.55, 0.45], [3.0, 1.0, -2.0]), ("tumbling-descent", [0.0, 0.3, 0.0, 0.1], [0.0, 10.0, 0.0])],
)
def test_kernel_matches_the_numpy_path_to_1e12_over_1000_steps(scene, throttles, wind) -> None:
    # Same equations in the same operation order: the only admissible differences are the
    # summation order of numpy's small dot products (a few ulp per step, amplified at most
    # linearly over 1000 steps of a non-chaotic flight) -> 1e-12 relative, the agreement the compiled paths are held to.
    sim, fl = _pair(scene, throttles, wind)
    ref = sim.y.copy()
    y = sim.y.copy()
    for i in range(1000):
        sim.integrator.step(sim.dynamics, i * sim.dt, ref, sim.dt)
    taken = fl.advance(y, np.empty(14), sim.dt, 1000)
    assert taken == 1000
    scale = np.maximum(np.abs(ref), 1e-9)  # components that are 0 stay 0 in both
    assert np.max(np.abs(y - ref) / scale) < 1e-12


def test_kernel_stops_after_the_step_that_empties_the_tank() -> None:
    # Full throttle burns 4 x 0.5 kg/s: 100 kg last 50 s = 5000 steps of 0.01 s; the kernel must
    # hand control back on that step so the simulation can force the throttles to 0.
    sim, fl = _pair("hover", [1.0, 1.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    y, yp = sim.y.copy(), np.empty(14)
    taken = fl.advance(y, yp, 0.01, 10_000)
    assert y[13] == 0.0 and yp[13] > 0.0
    assert abs(taken - 5000) <= 1


def test_kernel_stops_below_the_stop_radius_with_the_previous_state_kept() -> None:
    sim, fl = _pair("hover", [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    y, yp = sim.y.copy(), np.empty(14)
    r_stop = float(np.linalg.norm(y[0:3])) - 10.0  # 10 m below the start: a free fall of ~2.3 s
    taken = fl.advance(y, yp, 0.01, 100_000, stop_radius=r_stop)
    assert np.linalg.norm(y[0:3]) < r_stop <= np.linalg.norm(yp[0:3])
    assert taken < 1000


def test_supports_names_what_it_cannot_run() -> None:
    assert fast.supports(load_scene("hover"))
    assert fast.unsupported_reason(load_scene("hover"), integrator="rk4").startswith("integrator 'rk4'")
    assert fast.unsupported_reason(load_scene("rotor-euler")) is not None
