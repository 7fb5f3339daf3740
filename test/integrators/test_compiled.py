"""Compiled Runge-Kutta methods against their references (numpy integrators, scipy's DOP853).

The compiled kernels (:mod:`lander_sim.fast.rk_kernels`) do the numpy code's arithmetic in the
same order, except for a few reductions (``|q|^2``, the error norm's mean), so states agree to
round-off: 1e-12 relative to each part's size is the bound asked (measured 0 to 1e-14), and the
adaptive controllers take the very same steps (same accepted/rejected counts, evaluations, and in
global error control the same passes).
DOP853 follows scipy's ``solve_ivp`` step for step: same evaluations, same state to 1e-12.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lander_sim.fast.rk_kernels import compiled_model, dop853_span, dop853_tableau
from lander_sim.integrators import make
from lander_sim.integrators.base import derivative


def kepler():
    """A point-like body on a Kepler orbit, GM = a = 1, e = 0.3 (period 2 pi)."""
    from lander_sim.integrators.reference import kepler_state
    from lander_sim.physics.dynamics import LanderDynamics
    from lander_sim.physics.models import Inputs, InverseSquareGravity
    from lander_sim.physics.state import pack
    from lander_sim.physics.vehicle import Vehicle

    v = Vehicle(dry_mass=1.0, fuel_capacity=0.0, inertia_diag=(1.0, 1.0, 1.0))
    dyn = LanderDynamics(v, [InverseSquareGravity(gm=1.0)], "quaternion", True, Inputs(throttles=np.zeros(0)))
    r0, v0 = kepler_state(0.0, 1.0, 1.0, 0.3)
    return dyn, pack(r0, v0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.0), 2.0 * math.pi / 400


def top():
    """Torque-free asymmetric top I = (1, 2, 3) spun about the intermediate axis (Dzhanibekov)."""
    from lander_sim.physics.dynamics import LanderDynamics
    from lander_sim.physics.models import Inputs
    from lander_sim.physics.state import pack
    from lander_sim.physics.vehicle import Vehicle

    v = Vehicle(dry_mass=1.0, fuel_capacity=0.0, inertia_diag=(1.0, 2.0, 3.0))
    dyn = LanderDynamics(v, [], "quaternion", False, Inputs(throttles=np.zeros(0)))
    return dyn, pack(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.01, 2.0, 0.01]), 0.0), 0.01


def descent():
    """The lander descending from 10 km with drag, wind and slightly unequal thrust."""
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    sim = Simulation(load_scene("descent-10km"))
    sim.set_throttles([0.40, 0.42, 0.40, 0.42])
    sim.set_wind([5.0, 0.0, 2.0])
    return sim.dynamics, sim.y.copy(), 0.05


def rotor():
    """Seed 1's gimballed rotor: fixed pivot, a weight on the spin axis (a constant force at a body point)."""
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    sim = Simulation(load_scene("rotor-quaternion"))
    return sim.dynamics, sim.y.copy(), 0.01


PARTS = (slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13), slice(13, 14))
PROBLEMS = {"descent": descent, "kepler": kepler, "top": top, "rotor": rotor}


def _close(a: np.ndarray, b: np.ndarray, rel: float = 1e-12) -> bool:
    return all(np.max(np.abs(a[s] - b[s])) <= rel * max(np.max(np.abs(b[s])), 1e-300) for s in PARTS)


@pytest.mark.parametrize("name", PROBLEMS)
def test_compiled_rk4_equals_the_numpy_rk4(name):
    dyn, y0, dt = PROBLEMS[name]()
    assert compiled_model(dyn) is not None
    a, b = y0.copy(), y0.copy()
    fast, ref = make("rk4"), make("rk4", compiled=False)
    for i in range(200):
        fast.step(dyn, i * dt, a, dt)
        ref.step(dyn, i * dt, b, dt)
    assert _close(a, b)


def _both(method: str, name: str) -> tuple[np.ndarray, np.ndarray, int, int]:
    """200 steps of problem ``name`` compiled and in numpy: final states and evaluations of each."""
    dyn, y0, dt = PROBLEMS[name]()
    a, b = y0.copy(), y0.copy()
    fast, ref = make(method), make(method, compiled=False)
    e0 = dyn.evaluations
    for i in range(200):
        fast.step(dyn, i * dt, a, dt)
    e1 = dyn.evaluations
    for i in range(200):
        ref.step(dyn, i * dt, b, dt)
    return a, b, e1 - e0, dyn.evaluations - e1


@pytest.mark.parametrize("name", PROBLEMS)
def test_compiled_verlet_equals_the_numpy_verlet(name):
    # The top and the rotor are on a fixed pivot: the kernel leaves r and v alone (P_PIVOT).
    a, b, n_fast, n_ref = _both("verlet", name)
    assert n_fast == n_ref == 400
    assert _close(a, b)


@pytest.mark.parametrize("name", PROBLEMS)
def test_compiled_geometric_splitting_equals_the_numpy_one(name):
    a, b, n_fast, n_ref = _both("geometric", name)
    assert n_fast == n_ref
    assert _close(a, b)


@pytest.mark.parametrize("name", PROBLEMS)
@pytest.mark.parametrize("tol", [1e-5, 1e-9])
def test_compiled_adaptive_takes_the_numpy_steps(name, tol):
    dyn, y0, dt = PROBLEMS[name]()
    a, b = y0.copy(), y0.copy()
    fast, ref = make("adaptive", rtol=tol, atol=tol), make("adaptive", rtol=tol, atol=tol, compiled=False)
    e0 = dyn.evaluations
    for i in range(10):
        fast.step(dyn, i * 20 * dt, a, 20 * dt)
    e1 = dyn.evaluations
    for i in range(10):
        ref.step(dyn, i * 20 * dt, b, 20 * dt)
    assert (fast.accepted, fast.rejected, e1 - e0) == (ref.accepted, ref.rejected, dyn.evaluations - e1)
    assert fast.max_error == pytest.approx(ref.max_error, rel=1e-9)
    assert _close(a, b)


@pytest.mark.parametrize("name", ["kepler", "top", "rotor"])
def test_compiled_adaptive_global_error_control_takes_the_numpy_passes(name):
    dyn, y0, dt = PROBLEMS[name]()
    a, b = y0.copy(), y0.copy()
    opts = dict(rtol=1e-7, atol=1e-7, error_control="global")
    fast, ref = make("adaptive", **opts), make("adaptive", **opts, compiled=False)
    for i in range(3):
        fast.step(dyn, i * 50 * dt, a, 50 * dt)
        ref.step(dyn, i * 50 * dt, b, 50 * dt)
    assert (fast.passes, fast.accepted, fast.rejected) == (ref.passes, ref.accepted, ref.rejected)
    assert fast.max_global_error == pytest.approx(ref.max_global_error, rel=1e-9)
    assert _close(a, b)


@pytest.mark.parametrize("name", PROBLEMS)
def test_compiled_dop853_steps_as_scipy_dop853(name):
    from scipy.integrate import solve_ivp

    dyn, y0, dt = PROBLEMS[name]()
    T = 100 * dt
    acc = np.zeros(6)

    def f(t, y):
        out = np.empty_like(y)
        derivative(dyn, t, y, out, acc)
        return out

    sol = solve_ivp(f, (0.0, T), y0.copy(), method="DOP853", rtol=1e-8, atol=1e-8)
    cm = compiled_model(dyn)
    thr, wind = cm.inputs()
    y, stats = y0.copy(), np.zeros(3)
    assert dop853_span(y, T, 1e-8, 1e-8, cm.params, cm.force, cm.torque, cm.burn, thr, wind, cm.translation,
                       *dop853_tableau(), stats) == 0
    assert int(stats[2]) == sol.nfev
    assert _close(y, sol.y[:, -1])


@pytest.mark.parametrize("name", PROBLEMS)
def test_dop853_integrator_compiled_equals_scipy(name):
    dyn, y0, dt = PROBLEMS[name]()
    a, b = y0.copy(), y0.copy()
    fast, ref = make("dop853", rtol=1e-9, atol=1e-9), make("dop853", rtol=1e-9, atol=1e-9, compiled=False)
    for i in range(3):
        fast.step(dyn, i * 30 * dt, a, 30 * dt)
        ref.step(dyn, i * 30 * dt, b, 30 * dt)
    assert fast.accepted > 0
    assert _close(a, b)


def test_a_model_without_compiled_form_flies_the_numpy_code():
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    sim = Simulation(load_scene("tumbling-descent-mesh"))  # mesh drag: no compiled form
    assert compiled_model(sim.dynamics) is None
    a, b = sim.y.copy(), sim.y.copy()
    make("rk4").step(sim.dynamics, 0.0, a, 0.01)
    make("rk4", compiled=False).step(sim.dynamics, 0.0, b, 0.01)
    assert np.array_equal(a, b)


def test_cache_guard_drops_a_kernels_cache_when_a_dependency_changes(tmp_path):
    from lander_sim.fast.cache_guard import invalidate_if_changed

    mod, dep = tmp_path / "kernel.py", tmp_path / "callee.py"
    mod.write_text("x = 1\n")
    dep.write_text("y = 1\n")
    cache = tmp_path / "__pycache__"
    invalidate_if_changed(str(mod), str(dep))  # first sight: stamp written
    (cache / "kernel.f-3.py311.nbi").write_text("index")
    (cache / "kernel.f-3.py311.1.nbc").write_text("code")
    invalidate_if_changed(str(mod), str(dep))  # unchanged: the cache stays
    assert len(list(cache.glob("kernel.*.nb?"))) == 2
    dep.write_text("y = 2\n")
    invalidate_if_changed(str(mod), str(dep))  # the callee changed: the stale machine code goes
    assert list(cache.glob("kernel.*.nb?")) == []
