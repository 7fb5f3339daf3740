"""What the node needs from the core, in one place: build, step, read out, reset.

A thin wrapper over :class:`lander_sim.simulation.Simulation` (no physics here):
it builds the simulation with the node's overrides, gathers one
:class:`Readout` per publish tick from ``state()``, and computes the
integrator-health figures the diagnostics report from ``derived()``.

Per tick only what the messages carry is computed: ``Simulation.derived()``
also evaluates energy, potential and angular momentum (~80 us, measured with
cProfile, the largest cost of a tick), which only the 1 Hz diagnostics need.
:meth:`SimAdapter.readout` therefore computes altitude, climb rate and ground
speed from the state with the same definitions as ``derived()``; a unit test
(test/sim_node/test_ros_helpers.py) checks the two agree.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import rotation
from lander_sim.physics.events import Event, Phase
from lander_sim.physics.vehicle import Vehicle
from lander_sim.scenes import Scene, load_scene
from lander_sim.simulation import Simulation

#: LanderState.phase values (lander_interfaces/msg/LanderState.msg: PHASE_FLYING=0, LANDED=1, CRASHED=2).
PHASE_CODE = {Phase.FLYING: 0, Phase.LANDED: 1, Phase.CRASHED: 2}


@dataclass(frozen=True)
class Readout:
    """One instant of the simulation as the node publishes it (SI units, frames in the names).

    ``q`` is the core's world -> body quaternion ``(s, x, y, z)`` (eq 12-13); the
    conversion to ROS's body -> world orientation is in :mod:`lander_sim.ros.convert`.
    """

    t: float
    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    gimbal_lock: bool
    omega_B: np.ndarray
    altitude: float
    climb_rate: float
    ground_speed: float
    mass: float
    fuel: float
    throttles: np.ndarray
    phase: int
    parachute_deployed: bool
    stabiliser_on: bool


class SimAdapter:
    """The node's handle on one :class:`Simulation` of one scene."""

    def __init__(self, sim: Simulation, seed: int | None = None) -> None:
        self.sim = sim
        self.seed = seed  # None: the scene's own seed
        self._conservative = _is_conservative(sim.scene)
        self._thrust_used = False
        self._energy0 = sim.derived().energy
        self._planet_radius = sim.dynamics.planet_radius
        self._gimbal_threshold = sim.scene.gimbal_threshold

    # --- pass-through -------------------------------------------------------------------------

    @property
    def scene(self) -> Scene:
        return self.sim.scene

    @property
    def vehicle(self) -> Vehicle:
        return self.sim.scene.vehicle

    @property
    def dt(self) -> float:
        return self.sim.dt

    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def flying(self) -> bool:
        return self.sim.phase is Phase.FLYING

    @property
    def phase_name(self) -> str:
        return self.sim.phase.value

    def step(self, n: int) -> None:
        self.sim.step(n)

    def step_each(self, n: int, after: Callable[[Simulation, np.ndarray, float], None]) -> None:
        """Advance ``n`` steps one at a time, calling ``after(sim, y_before, dt)`` after each (the
        state before the step and its length [s]: what the sensors sample)."""
        sim = self.sim
        for _ in range(n):
            y_before, t_before = sim.y.copy(), sim.t
            sim.step(1)
            after(sim, y_before, sim.t - t_before)

    def set_throttles(self, throttles: Sequence[float]) -> None:
        """Validated by the core (``InputError`` on a bad command, state untouched)."""
        self.sim.set_throttles(throttles)
        if any(x != 0.0 for x in throttles):
            self._thrust_used = True

    def zero_throttles(self) -> None:
        self.sim.set_throttles(np.zeros(self.vehicle.n_thrusters))

    def set_wind(self, wind_W: Sequence[float]) -> None:
        self.sim.set_wind(wind_W)

    @property
    def mean_wind_W(self) -> np.ndarray:
        """The mean wind in force, world frame [m/s]."""
        return self.sim.mean_wind_W

    def set_stabiliser(self, on: bool) -> None:
        self.sim.set_stabiliser(on)

    def deploy_parachute(self) -> None:
        self.sim.deploy_parachute()

    def drain_events(self) -> list[Event]:
        return self.sim.drain_events()

    def reset(self, seed: int | None = None) -> None:
        """Back to the scene's initial state, bit for bit; ``seed`` re-seeds the stochastic models (gusts)
        and stays in force for later resets (None: the seed already in force)."""
        if seed is not None:
            self.seed = seed
        self.sim.reset(seed=self.seed)
        self._thrust_used = False
        self._energy0 = self.sim.derived().energy

    # --- read-out -----------------------------------------------------------------------------

    def readout(self) -> Readout:
        """The instant to publish: the state plus the derived quantities the messages carry.

        Altitude ``|r_W| - R_planet``, climb rate ``v_W . r_hat`` (radial, positive up) and
        ground speed ``|v_W - climb r_hat|`` as in ``Simulation.derived()``.
        """
        s = self.sim.state()
        r, v = s.r_W, s.v_W
        rn = math.sqrt(float(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]))
        if rn > 0.0:
            climb = float(v[0] * r[0] + v[1] * r[1] + v[2] * r[2]) / rn
            h = v - (climb / rn) * r
            ground = math.sqrt(float(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]))
        else:
            climb, ground = 0.0, math.sqrt(float(v @ v))
        chute = self.sim.parachute
        return Readout(
            t=s.t,
            r_W=r,
            v_W=v,
            q=s.q,
            euler=s.euler,
            gimbal_lock=rotation.near_gimbal_lock(s.euler, self._gimbal_threshold),
            omega_B=s.omega_B,
            altitude=rn - self._planet_radius,
            climb_rate=climb,
            ground_speed=ground,
            mass=self.vehicle.mass(s.fuel),
            fuel=s.fuel,
            throttles=self.sim.throttles,
            phase=PHASE_CODE[self.sim.phase],
            parachute_deployed=chute is not None and chute.status.value == "deployed",
            stabiliser_on=bool(self.sim.stabiliser),
        )

    def health_values(self) -> dict[str, str]:
        """Integrator health for the diagnostics: |q| drift always, energy drift where energy is conserved."""
        d = self.sim.derived()
        out = {"quaternion_norm_drift": f"{d.quat_norm_error:.3e}", "integrator": self.sim.integrator.name}
        if self._conservative and not self._thrust_used and self.flying:
            scale = max(abs(self._energy0), 1e-300)
            out["energy_relative_drift"] = f"{(d.energy - self._energy0) / scale:.3e}"
        else:
            out["energy_relative_drift"] = "n/a (non-conservative: thrust, drag, parachute or touchdown)"
        return out


def _is_conservative(scene: Scene) -> bool:
    """True when every force model the scene switches on conserves energy (no air, no ground)."""
    return not {"atmosphere", "drag", "parachute", "ground"} & set(scene.models.configs)


def build_simulation(
    name: str,
    integrator: str | None = None,
    dt: float | None = None,
    gimbal_threshold: float | None = None,
    seed: int | None = None,
) -> SimAdapter:
    """Load scene ``name`` (name, alias or path) and build its simulation with the node's overrides.

    Raises ``SceneError`` (unknown scene, bad file) or ``ValueError`` (bad integrator or dt),
    whose messages name what was wrong.

    A scratch copy takes one step first: the first step in a process loads the compiled kernels
    (0.3-0.4 s measured), which must happen here, at start-up or a scene load, and not in the
    running loop's first tick, which would start a real-time flight that far behind its schedule.
    """
    scene = load_scene(name)
    if gimbal_threshold is not None:
        scene = dataclasses.replace(scene, gimbal_threshold=gimbal_threshold)
    Simulation(scene, integrator=integrator, dt=dt).step(1)
    adapter = SimAdapter(Simulation(scene, integrator=integrator, dt=dt), seed=seed)
    if seed is not None:
        adapter.reset(seed)
    return adapter
