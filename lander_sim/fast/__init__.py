"""Compiled fast path: many velocity-Verlet steps of the standard lander model in one call.

Use it when :func:`supports` says the scene's models are exactly the supported set and, at run
time, :meth:`FastLander.usable` holds (no stabiliser, parachute not deployed). Otherwise step
with the normal integrator + :class:`~lander_sim.physics.dynamics.LanderDynamics` path, which is
also the fallback when numba is missing (``HAVE_NUMBA``); both give the same numbers to ~1e-12.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from lander_sim.fast import lander_kernel as _k
from lander_sim.fast.lander_kernel import HAVE_NUMBA

__all__ = ["HAVE_NUMBA", "FastLander", "supports", "unsupported_reason"]

#: Scene models (keys of lander_sim.physics.models.table.MODELS) the kernel has (ground: the caller's).
_SUPPORTED = {"gravity", "atmosphere", "drag", "parachute", "thrusters", "ground"}


def unsupported_reason(scene: Any, integrator: str | None = None) -> str | None:
    """Why the fast path cannot run ``scene`` (None if it can). ``integrator`` overrides the scene's."""
    m = scene.models
    if (integrator or scene.integrator) != "verlet":
        return f"integrator {(integrator or scene.integrator)!r} (fast path is velocity Verlet only)"
    if scene.attitude != "quaternion":
        # Not the kernel's limit (verlet_step flies Euler angles: the integrator's compiled Verlet
        # runs them one step per call) but its callers': the Simulation checks gimbal lock after
        # each multi-step call, so an entry inside one would fire late or not at all, and the
        # batched sweep's compiled controllers read y[6:10] as a quaternion.
        return ("Euler-angle attitude (the multi-step fast path and the batched sweep are quaternion only; "
                "the compiled Verlet steps Euler scenes one step per call)")
    if not scene.translation:
        return "fixed pivot"
    other = sorted(set(m.configs) - _SUPPORTED)
    if other:
        return f"model(s) {', '.join(other)} (fast path: {', '.join(sorted(_SUPPORTED))})"
    gravity, drag = m.get("gravity"), m.get("drag")
    if gravity is None or gravity.kind != "inverse-square":
        return "gravity must be inverse-square"
    if drag is not None and drag.kind != "sphere":
        return f"drag kind {drag.kind!r} (fast path has sphere drag only)"
    if scene.vehicle.gyration_sq is None and scene.vehicle.inertia_diag is None:
        return "vehicle without inertia"
    return None


def supports(scene: Any, integrator: str | None = None) -> bool:
    """True if the scene's models are a subset of: inverse-square gravity, atmosphere, sphere drag,
    thrusters, parachute (packed) and ground (handled by the caller), with Verlet and quaternions."""
    return unsupported_reason(scene, integrator) is None


class FastLander:
    """Parameters of one :class:`~lander_sim.physics.dynamics.LanderDynamics` packed for the kernel.

    Built once; inputs (throttles, wind) are read from the dynamics' shared ``inputs`` object at
    each :meth:`advance`, so the usual ``set_throttles``/``set_wind`` keep working.
    """

    def __init__(self, dyn: Any, renormalise: bool = True) -> None:
        from lander_sim.fast.rk_kernels import CompiledModel

        names = {m.name: m for m in dyn.models}
        unknown = set(names) - {"gravity", "drag", "parachute", "thrusters"}
        if unknown:
            raise ValueError(f"fast path does not support model(s) {', '.join(sorted(unknown))}")
        if dyn.attitude != "quaternion" or not dyn.translation:
            raise ValueError("fast path needs quaternion attitude and free translation")
        g = names.get("gravity")
        if g is None or not hasattr(g, "gm"):
            raise ValueError("fast path needs inverse-square gravity")
        d = names.get("drag")
        if d is not None and not hasattr(d, "cd"):
            raise ValueError("fast path supports sphere drag only")
        # The packing is the compiled Runge-Kutta methods' (one layout, lander_kernel.P_*).
        model = CompiledModel(dyn)
        self.dyn = dyn
        self.params = model.params.copy()
        self.params[_k.P_RENORM] = 1.0 if renormalise else 0.0
        self.force, self.torque, self.burn = model.force, model.torque, model.burn
        self._parachute = names.get("parachute")

    def usable(self, stabiliser: bool = False) -> bool:
        """Run-time check: no stabiliser and no deployed parachute (the kernel has neither)."""
        chute = self._parachute
        deployed = chute is not None and getattr(chute.status, "value", "") == "deployed"
        return not stabiliser and not deployed

    def advance(self, y: np.ndarray, y_prev: np.ndarray, dt: float, n: int, stop_radius: float = 0.0) -> int:
        """Up to ``n`` Verlet steps in place (see :func:`lander_kernel.verlet_steps`); returns the steps taken.

        Early stop after the step that goes below ``stop_radius`` [m] or empties the tank under
        throttle; ``y_prev`` is the state before the last step (for touchdown interpolation).
        """
        inputs = self.dyn.inputs
        taken = _k.verlet_steps(
            y, y_prev, int(n), float(dt), self.params, self.force, self.torque, self.burn,
            np.ascontiguousarray(inputs.throttles, dtype=float), np.ascontiguousarray(inputs.wind_W, dtype=float),
            float(stop_radius),
        )
        self.dyn.evaluations += 2 * taken
        return int(taken)
