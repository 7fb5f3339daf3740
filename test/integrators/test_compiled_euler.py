"""Compiled methods in Euler-angle attitude mode (eq 3, 5, 6) against the numpy path.

The kernels (:mod:`lander_sim.fast.lander_kernel`, :mod:`lander_sim.fast.rk_kernels`) compute
``R(E)`` (eq 3), ``J(E)`` with ``|sin theta|`` floored at ``rotation.SIN_THETA_FLOOR`` (eq 5) and
``J'`` (eq 7) with the numpy code's scalar operations in its order; the one difference is the
3-term products ``J @ omega``, which numpy hands to BLAS (fused multiply-adds on this machine) and
the kernels sum left to right: at most 2 gamma_3 sum_j |J_ij w_j| apart per row (gamma_3 = 3 eps /
(1 - 3 eps), each sum within gamma_3 of the exact one). Over the scenes below that stays at
round-off (measured 0 to 5e-13, the largest from DOP853 against scipy), so 1e-12 relative to each
part's size is the bound, as for the quaternion scenes (test_compiled.py), with the same
evaluations and, for the adaptive methods, the same accepted/rejected steps and passes.
At gimbal lock (the pendulum, the upright lander) the floored J is 1e12 and the angles run to
1e8-1e10 rad ("finite but wrong"); those numbers agree as well (bit for bit on the pendulum), so
the gimbal-lock events fire at the same step on both paths.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import yaml

from lander_sim import fast
from lander_sim.fast import lander_kernel as lk
from lander_sim.fast.rk_kernels import compiled_model, geometric_steps
from lander_sim.integrators import IntegratorError, make
from lander_sim.physics import rotation
from lander_sim.scenes import Scene, load_scene, parse_scene
from lander_sim.scenes.loader import SCENE_DIR
from lander_sim.simulation import Simulation

if not fast.HAVE_NUMBA:  # without numba the "compiled" kernels are the same source run as Python
    pytestmark = pytest.mark.skip(reason="numba is not importable")

PARTS = (slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13), slice(13, 14))
THROTTLES = [0.40, 0.45, 0.40, 0.42]
WIND = [5.0, 0.0, 2.0]


def _lander_euler(base: str, euler_deg: list[float]) -> Scene:
    """A packaged lander scene flown in Euler-angle mode from the given ZXZ angles, no stabiliser."""
    data = yaml.safe_load((SCENE_DIR / f"{base}.yaml").read_text())
    data["attitude_mode"] = "euler"
    data["initial"]["attitude"] = {"euler_deg": euler_deg}
    data["stabiliser"] = False
    return parse_scene(data, f"{base}-euler.yaml")


#: name -> (scene, steps of the scene's dt). The lander runs end before touchdown: the impact
#: interpolation divides by the last step's drop (~1 m), which turns round-off of |r| = 3.4e6 m
#: into 1e-11 of the interpolated attitude on both paths alike (a property of that division).
SCENES: dict[str, tuple[Any, int]] = {
    "rotor-euler": (lambda: load_scene("rotor-euler"), 1000),
    "gimbal-lock-pendulum": (lambda: load_scene("gimbal-lock-pendulum"), 1000),
    "gimbal-lock-close": (lambda: load_scene("gimbal-lock-close"), 1000),
    # Tumbling descent (sphere drag, wind, thrust, inverse-square gravity) away from the lock.
    "lander-tumbling-euler": (lambda: _lander_euler("tumbling-descent", [30.0, 60.0, -20.0]), 300),
    # Upright lander in Euler mode: E = 0 is gimbal lock, so this flies the floored J with thrust.
    "lander-upright-euler": (lambda: _lander_euler("hover", [0.0, 0.0, 0.0]), 150),
}


def _sim(name: str, integrator: str, compiled: bool, **options: Any) -> Simulation:
    sim = Simulation(SCENES[name][0](), integrator=integrator, use_fast_path=compiled)
    for key, value in options.items():
        setattr(sim.integrator, key, value)
    if sim.scene.vehicle.n_thrusters:
        sim.set_throttles(THROTTLES)
        sim.set_wind(WIND)
    return sim


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference of each part of the state relative to that part's size in ``b``."""
    return max(float(np.max(np.abs(a[s] - b[s]))) / max(float(np.max(np.abs(b[s]))), 1e-300) for s in PARTS)


def _events(sim: Simulation) -> list[tuple[str, float]]:
    return [(e.kind.value, e.t) for e in sim.drain_events()]


def _fly_pair(name: str, integrator: str, **options: Any) -> tuple[Simulation, Simulation]:
    """The scene flown by the compiled method and by the numpy reference, same steps.

    A step-size underflow must happen on both paths at the same step (then the counters are
    compared as they stand); the pendulum at tol 1e-9 does that in its first step: at the lock
    J = 1e12, and no step size meets that tolerance (h = 8.3e-15 s on both)."""
    n = SCENES[name][1]
    fast_sim, ref_sim = _sim(name, integrator, True, **options), _sim(name, integrator, False, **options)
    assert fast_sim.scene.attitude == "euler"
    assert compiled_model(fast_sim.dynamics) is not None
    assert getattr(ref_sim.integrator, "compiled", True) is False
    failed = []
    for sim in (fast_sim, ref_sim):
        for k in range(n):
            try:
                sim.step(1)
            except FloatingPointError:
                failed.append(k)
                break
    assert failed == [] or failed == [failed[0]] * 2, f"only one path underflowed, or at different steps: {failed}"
    return fast_sim, ref_sim


def _numpy_model_calls(sim: Simulation) -> int:
    return sum(int(getattr(m, "calls", 0)) for m in sim.dynamics.models)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("integrator", ["verlet", "rk4"])
def test_compiled_fixed_step_methods_equal_the_numpy_ones_in_euler_mode(name: str, integrator: str) -> None:
    a, b = _fly_pair(name, integrator)
    assert _numpy_model_calls(a) == 0 < _numpy_model_calls(b)  # the compiled run never ran the numpy models
    assert a.dynamics.evaluations == b.dynamics.evaluations
    assert a.y[9] == b.y[9] == 0.0  # slot 9 is unused in Euler mode: never renormalised into
    assert _rel(a.y, b.y) <= 1e-12
    assert _events(a) == _events(b)


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("tol", [1e-5, 1e-9])
def test_compiled_adaptive_takes_the_numpy_steps_in_euler_mode(name: str, tol: float) -> None:
    a, b = _fly_pair(name, "adaptive", rtol=tol, atol=tol)
    fa, fb = a.integrator, b.integrator
    assert (fa.accepted, fa.rejected, a.dynamics.evaluations) == (fb.accepted, fb.rejected, b.dynamics.evaluations)
    # The estimate is a difference of two solutions normalised by atol + rtol |y| ~ tol |y|: states
    # agreeing to 1e-12 relative make it agree to 1e-12 / tol (Euler mode differs by a few ulp, not 0).
    assert abs(fa.max_error - fb.max_error) <= 1e-12 / tol
    assert _rel(a.y, b.y) <= 1e-12
    assert _events(a) == _events(b)


@pytest.mark.parametrize("name", SCENES)
def test_compiled_adaptive_global_error_control_takes_the_numpy_passes_in_euler_mode(name: str) -> None:
    a, b = _fly_pair(name, "adaptive", rtol=1e-7, atol=1e-7, error_control="global")
    fa, fb = a.integrator, b.integrator
    assert (fa.passes, fa.accepted, fa.rejected, a.dynamics.evaluations) == (
        fb.passes, fb.accepted, fb.rejected, b.dynamics.evaluations)
    assert abs(fa.max_global_error - fb.max_global_error) <= 1e-12 / 1e-7  # as above
    assert _rel(a.y, b.y) <= 1e-12
    assert _events(a) == _events(b)


@pytest.mark.parametrize("name", SCENES)
def test_compiled_dop853_equals_scipy_in_euler_mode(name: str) -> None:
    # The reference is scipy's solve_ivp(DOP853) on the numpy first-order form (eq 5 for E').
    a, b = _fly_pair(name, "dop853", rtol=1e-9, atol=1e-9)
    assert a.integrator.accepted > 0
    assert a.dynamics.evaluations == b.dynamics.evaluations  # scipy's steps, evaluation for evaluation
    assert _rel(a.y, b.y) <= 1e-12
    assert _events(a) == _events(b)


@pytest.mark.parametrize("integrator", ["verlet", "rk4", "adaptive"])
def test_gimbal_lock_events_fire_at_the_same_step(integrator: str) -> None:
    # gimbal-lock-close enters |sin theta| < 0.5 six times in 10 s; compare the step of each entry.
    a, b = _fly_pair("gimbal-lock-close", integrator)
    ea, eb = _events(a), _events(b)
    assert len(ea) >= 6 and all(kind == "gimbal_lock" for kind, _ in ea)
    assert [round(t / a.dt) for _, t in ea] == [round(t / b.dt) for _, t in eb]


def test_euler_scenes_run_the_compiled_verlet_one_step_at_a_time() -> None:
    # The multi-step fast path (FastLander, and the batched sweep built on it) stays quaternion
    # only: the Simulation checks gimbal lock after each kernel call, not each step. Verlet still
    # runs compiled, through the integrator's own dispatch.
    scene = _lander_euler("tumbling-descent", [30.0, 60.0, -20.0])
    why = fast.unsupported_reason(scene)
    assert why is not None and why.startswith("Euler-angle attitude")
    sim = Simulation(scene)
    assert not sim.fast_path and compiled_model(sim.dynamics) is not None
    sim.step(10)
    assert _numpy_model_calls(sim) == 0


def test_the_packed_model_carries_the_mode_and_the_numpy_floor() -> None:
    cm = compiled_model(Simulation(load_scene("rotor-euler")).dynamics)
    assert cm is not None
    assert (cm.params[lk.P_EULER], cm.params[lk.P_PIVOT]) == (1.0, 1.0)
    assert cm.params[lk.P_SIN_FLOOR] == rotation.SIN_THETA_FLOOR
    cq = compiled_model(Simulation(load_scene("hover")).dynamics)
    assert cq is not None
    assert (cq.params[lk.P_EULER], cq.params[lk.P_PIVOT]) == (0.0, 0.0)


ANGLES = [(0.3, 1.1, -2.0), (2.0, 0.0, 0.7), (-1.0, math.pi, 0.2), (0.5, -1e-13, 1.3), (0.1, math.pi / 2, -0.4),
          (1e10, 5e7, -1e10)]


@pytest.mark.parametrize("E", ANGLES)
def test_kernel_J_and_J_dot_are_the_numpy_entries_exactly(E: tuple[float, float, float]) -> None:
    # Same scalar operations, same libm: bit for bit, including at the floored lock (theta = 0, pi).
    floor = rotation.SIN_THETA_FLOOR
    J = rotation.euler_rates_matrix(np.array(E))
    assert np.array_equal(np.array(lk.euler_rates_matrix(E[1], E[2], floor)), J[:, 0:2].ravel())
    assert np.array_equal(J[:, 2], [0.0, 0.0, 1.0])
    Ed = np.array([0.3, -0.7, 1.9])
    Jd = rotation.euler_rates_matrix_dot(np.array(E), Ed)
    assert np.array_equal(np.array(lk.euler_rates_matrix_dot(E[1], E[2], Ed[1], Ed[2], floor)), Jd[:, 0:2].ravel())
    assert np.array_equal(Jd[:, 2], np.zeros(3))
    # E' = J w: numpy's J @ w and the kernel's left-to-right sum differ by at most 2 gamma_3 sum_j |J_ij w_j|.
    w = np.array([0.8, -1.3, 2.2])
    y = np.zeros(14)
    y[6:9], y[10:13] = E, w
    eps = np.finfo(float).eps
    bound = 2.0 * (3 * eps / (1 - 3 * eps)) * (np.abs(J) @ np.abs(w))
    assert np.all(np.abs(np.array(lk.euler_rates(y, floor)) - J @ w) <= bound)


def test_geometric_declines_euler_mode_with_its_reason() -> None:
    sim = Simulation(load_scene("rotor-euler"), integrator="rk4")
    with pytest.raises(IntegratorError, match="needs attitude 'quaternion'"):
        make("geometric").step(sim.dynamics, 0.0, sim.y.copy(), 0.01)
    cm = compiled_model(sim.dynamics)
    assert cm is not None
    thr, wind = cm.inputs()
    with pytest.raises(ValueError, match="quaternion-only"):
        geometric_steps(sim.y.copy(), 0.01, 1, cm.params, cm.force, cm.torque, cm.burn, thr, wind, cm.translation, False)
