"""The Simulation: steps a scene, takes inputs, reports events and derived quantities.

No ROS here: the node (``lander_sim.node``) drives this object. Inputs are piecewise
constant over a step. Bad input raises :class:`lander_sim.errors.InputError`, leaves
the state untouched and is counted in :attr:`Simulation.rejected`.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from lander_sim import fast, integrators
from lander_sim.errors import InputError
from lander_sim.integrators.base import Integrator
from lander_sim.physics import rotation
from lander_sim.physics.dynamics import LanderDynamics
from lander_sim.physics.events import Event, EventKind, Phase
from lander_sim.physics.models import Air, ChuteStatus, ForceModel, Inputs, Parachute, Surface
from lander_sim.physics.models.base import BuildContext
from lander_sim.physics.models.stabiliser import stabilise
from lander_sim.physics.models.table import MODELS
from lander_sim.physics.rigid_body import kinetic_energy
from lander_sim.physics.state import ATT, EULER, FUEL, OMEGA_B, R_W, V_W, StateView
from lander_sim.physics.wind import GustProcess, WindError
from lander_sim.scenes import Scene

__all__ = ["Derived", "Event", "EventKind", "Phase", "Simulation", "Snapshot", "build_dynamics", "compose"]


def compose(scene: Scene, inputs: Inputs) -> tuple[LanderDynamics, Surface | None]:
    """The models a scene switches on, built through the models table
    (:data:`lander_sim.physics.models.table.MODELS`, in its order; others are not built at all),
    composed into a :class:`LanderDynamics`; and the ground, if the scene has one."""
    ctx = BuildContext(vehicle=scene.vehicle)
    forces: list[ForceModel] = []
    atmosphere: Air | None = None
    ground: Surface | None = None
    for key, cfg in scene.models.configs.items():
        built = MODELS[key].build(cfg, ctx)
        forces.extend(built.forces)
        atmosphere = built.atmosphere or atmosphere
        ground = built.ground or ground
        if built.planet_radius is not None:
            ctx = replace(ctx, planet_radius=built.planet_radius)
    dyn = LanderDynamics(scene.vehicle, forces, scene.attitude, scene.translation, inputs, atmosphere, ctx.planet_radius)
    return dyn, ground


def build_dynamics(scene: Scene, inputs: Inputs) -> LanderDynamics:
    """The dynamics of :func:`compose` alone."""
    return compose(scene, inputs)[0]


@dataclass(frozen=True)
class Derived:
    """Quantities derived from the state (SI units).

    Attributes
    ----------
    altitude : float
        ``|r_W| - R`` [m] (distance from the origin in planet-less scenes).
    climb_rate : float
        ``v_W . r_hat`` [m/s].
    ground_speed : float
        Horizontal speed ``|v_W - (v_W . r_hat) r_hat|`` [m/s] (planet rotation ignored).
    mass : float
        [kg].
    kinetic_energy : float
        Translational (if translation is on) + rotational kinetic energy [J].
    potential_energy : float
        Gravity (``-GM m / |r|`` or ``-m g . r``) + the constant force's potential [J].
    energy : float
        Sum of the two [J] (conserved when only conservative models are on).
    angular_momentum_W : ndarray (3,)
        Spin angular momentum ``R^T I omega_B`` about the centre of mass (or pivot), world frame [kg m^2/s].
    euler : ndarray (3,)
        ZXZ angles (phi, theta, psi) [rad].
    gimbal_lock : bool
        ``|sin theta| < gimbal_threshold``.
    quat_norm_error : float
        ``|q| - 1`` (0 in Euler mode).
    """

    altitude: float
    climb_rate: float
    ground_speed: float
    mass: float
    kinetic_energy: float
    potential_energy: float
    energy: float
    angular_momentum_W: np.ndarray
    euler: np.ndarray
    gimbal_lock: bool
    quat_norm_error: float


@dataclass(frozen=True)
class Snapshot:
    """Everything needed to continue bit-exactly from an instant (see :meth:`Simulation.restore`)."""

    y: np.ndarray
    k: int
    throttles: np.ndarray
    wind_W: np.ndarray
    phase: Phase
    chute: ChuteStatus | None
    stabiliser: bool
    near_lock: bool
    fuel_out: bool
    integrator: Integrator
    mean_wind_W: np.ndarray | None = None
    gusts: tuple[dict[str, Any], np.ndarray, int] | None = None  #: GustProcess.get_state()
    failed: np.ndarray | None = None


class Simulation:
    """Steps a :class:`~lander_sim.scenes.Scene` with a fixed step.

    Parameters
    ----------
    scene : Scene
    integrator : str, optional
        Overrides the scene's integrator (a name of ``lander_sim.integrators.REGISTRY``).
    dt : float, optional
        Overrides the scene's step [s].
    use_fast_path : bool
        Step with the compiled kernel (:mod:`lander_sim.fast`) whenever the scene and the moment
        allow it (Verlet, quaternions, the standard lander models, no stabiliser or open
        parachute); the numpy path is the fallback and agrees to ~1e-12 relative. False also
        builds the integrator with ``compiled=False`` (its numpy code, the reference).

    Wind is the mean (``scene.wind_W``, replaced by :meth:`set_wind`) plus the scene's gusts
    (``scene.gust``, :class:`~lander_sim.physics.wind.GustProcess`), advanced once per physics
    step: the step is the simulation's only clock, so the gusts (like everything else) do not
    depend on how callers group steps (``step(10)`` or ten ``step(1)``), on the control rate or on
    the path (compiled kernel or numpy), and a re-flight from the same seed is bit-identical.
    Scheduled thruster failures (``scene.thruster_failures``) take effect at the first step starting
    at or after their time: the thruster's throttle is held at 0 from then on.
    """

    def __init__(
        self, scene: Scene, integrator: str | None = None, dt: float | None = None, use_fast_path: bool = True
    ) -> None:
        self.scene = scene
        name = integrator or scene.integrator
        # Scene options belong to the scene's method; an overriding method starts from its defaults.
        options = dict(scene.integrator_options) if name == scene.integrator else {}
        if not use_fast_path and "compiled" in integrators.options_of(name):
            options["compiled"] = False  # the numpy reference all the way, not only for Verlet's kernel
        self.integrator = integrators.make(name, **options)
        step = scene.dt if dt is None else dt
        if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0.0):
            raise InputError(f"dt must be a positive finite number of seconds, got {step!r}")
        self.dt = float(step)
        self.inputs = Inputs(throttles=np.zeros(scene.vehicle.n_thrusters), wind_W=np.array(scene.wind_W, dtype=float))
        self._mean_wind_W = np.array(scene.wind_W, dtype=float)
        self.gusts: GustProcess | None = GustProcess(scene.gust, self.dt) if scene.gust is not None else None
        self._failed = np.zeros(scene.vehicle.n_thrusters, dtype=bool)
        self._failures: list[tuple[int, int]] = []
        self.dynamics, self.ground = compose(scene, self.inputs)
        chute = self.dynamics.model("parachute")
        self.parachute: Parachute | None = chute if isinstance(chute, Parachute) else None
        self.rejected: dict[str, int] = {"throttles": 0, "wind": 0, "parachute": 0, "stabiliser": 0}
        self.y = np.empty_like(scene.initial_state)
        self._y_prev = np.empty_like(self.y)
        self._fast: fast.FastLander | None = None
        if use_fast_path and fast.HAVE_NUMBA and fast.supports(scene, name):
            self._fast = fast.FastLander(self.dynamics, renormalise=getattr(self.integrator, "renormalise", True))
        self.reset()

    # --- lifecycle ---------------------------------------------------------------

    def reset(self, seed: int | None = None) -> None:
        """Back to the scene's initial state at t = 0 (the ``rejected`` counts are kept).

        ``seed`` re-seeds the gusts (an integer in [0, 2**63)) and stays in force for later resets;
        None restarts them from the seed in force (the scene's ``wind.gust.seed`` until a seed is
        given), so a plain reset replays the same flight bit for bit. The mean wind goes back to
        the scene's; no thruster has failed yet.
        """
        if self.gusts is not None:
            try:
                self.gusts.reset(seed)
            except WindError as exc:
                raise InputError(f"reset: {exc}") from None
        elif seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise InputError(f"reset: seed must be an integer in [0, 2**63), got {seed!r}")
        np.copyto(self.y, self.scene.initial_state)
        self._k = 0
        self.inputs.throttles[:] = 0.0
        self._mean_wind_W[:] = self.scene.wind_W
        self._failed[:] = False
        self._schedule_failures()
        self._update_wind()
        self.phase = Phase.FLYING
        self.stabiliser = self.scene.stabiliser
        self._events: list[Event] = []
        self._fuel_out = False
        self._near_lock = False
        if self.parachute is not None:
            self.parachute.status = ChuteStatus.NOT_DEPLOYED
        reset_integrator = getattr(self.integrator, "reset", None)
        if reset_integrator is not None:
            reset_integrator()  # e.g. the adaptive method's step size: same start, same flight
        self._check_gimbal()

    @property
    def t(self) -> float:
        """Simulation time [s]; counted in whole steps so it never drifts."""
        return self._k * self.dt

    # --- inputs ----------------------------------------------------------------

    def _reject(self, kind: str, msg: str) -> InputError:
        self.rejected[kind] = self.rejected.get(kind, 0) + 1
        return InputError(msg)

    def set_throttles(self, throttles: Sequence[float] | np.ndarray) -> None:
        """Throttle per thruster, each in [0, 1]; held until changed. Forced to 0 once landed or out of fuel."""
        try:
            t = np.asarray(throttles, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise self._reject("throttles", f"throttles must be a sequence of numbers, got {throttles!r}") from None
        n = self.scene.vehicle.n_thrusters
        if t.shape != (n,):
            raise self._reject("throttles", f"throttles must have {n} values (one per thruster), got {t.size}")
        for i, x in enumerate(t.tolist()):
            if not math.isfinite(x) or x < 0.0 or x > 1.0:
                raise self._reject("throttles", f"throttles[{i}] must be a finite number in [0, 1], got {float(x)!r}")
        if self.phase is Phase.FLYING and not self._fuel_out:
            self.inputs.throttles[:] = t
            self.inputs.throttles[self._failed] = 0.0  # a failed thruster ignores its command

    def set_wind(self, wind_W: Sequence[float]) -> None:
        """Mean wind velocity, world frame [m/s] (replaces the scene's; the gusts, if any, ride on it).
        Used by the drag and parachute models."""
        try:
            w = np.asarray(wind_W, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise self._reject("wind", f"wind must be 3 numbers (world frame, m/s), got {wind_W!r}") from None
        if w.shape != (3,) or not np.all(np.isfinite(w)):
            raise self._reject("wind", f"wind must be 3 finite numbers (world frame, m/s), got {wind_W!r}")
        self._mean_wind_W[:] = w
        self._update_wind()

    def _update_wind(self) -> None:
        """The wind the models see: mean + current gust (in place, no allocation)."""
        w = self.inputs.wind_W
        w[:] = self._mean_wind_W
        if self.gusts is not None:
            w += self.gusts.gust_W

    @property
    def mean_wind_W(self) -> np.ndarray:
        """The mean wind in force, world frame [m/s] (a copy); ``inputs.wind_W`` adds the gust."""
        return self._mean_wind_W.copy()

    @property
    def failed_thrusters(self) -> tuple[int, ...]:
        """Indices of the thrusters that have failed so far."""
        return tuple(int(i) for i in np.flatnonzero(self._failed))

    def _schedule_failures(self) -> None:
        """Pending failures as ``(step index, thruster)``, soonest first: the first step starting at or
        after the failure time (the 1e-9 absorbs the rounding of ``time / dt``)."""
        self._failures = sorted(
            (max(0, math.ceil(f.time / self.dt - 1e-9)), f.thruster)
            for f in self.scene.thruster_failures if not self._failed[f.thruster]
        )

    def _apply_due_failures(self) -> None:
        """Fail every thruster whose failure step has come (the step about to start is ``_k``)."""
        while self._failures and self._failures[0][0] <= self._k:
            _, i = self._failures.pop(0)
            self._failed[i] = True
            self.inputs.throttles[i] = 0.0

    def set_stabiliser(self, on: bool) -> None:
        """Switch the attitude stabiliser aid on or off."""
        if not isinstance(on, (bool, np.bool_)):
            raise self._reject("stabiliser", f"stabiliser must be true or false, got {on!r}")
        self.stabiliser = bool(on)

    def deploy_parachute(self) -> ChuteStatus:
        """Deploy the parachute (lost at once if faster than its limit inside the atmosphere)."""
        if self.parachute is None:
            raise self._reject("parachute", f"scene {self.scene.name!r} has no parachute (models.parachute is off)")
        before = self.parachute.status
        ctx = self.dynamics.fill_context(self.y)
        speed = float(np.linalg.norm(self.inputs.wind_W - self.y[V_W]))
        inside = self.dynamics.atmosphere is not None and ctx.altitude < self.dynamics.atmosphere.exosphere
        status = self.parachute.deploy(speed, inside)
        if status is not before:
            kind = EventKind.PARACHUTE_DEPLOYED if status is ChuteStatus.DEPLOYED else EventKind.PARACHUTE_LOST
            self._emit(kind, f"parachute {status.value} at airspeed {speed:.1f} m/s", {"airspeed": speed})
        return status

    # --- stepping --------------------------------------------------------------

    @property
    def fast_path(self) -> bool:
        """True when :meth:`step` can use the compiled kernel right now."""
        return self._fast is not None and self._fast.usable(self.stabiliser)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``. After touchdown the clock runs on with the state frozen."""
        y, y_prev, dyn, integ, dt = self.y, self._y_prev, self.dynamics, self.integrator, self.dt
        remaining = n
        gusts = self.gusts
        while remaining > 0:
            if self.phase is not Phase.FLYING:
                self._k += remaining
                return
            if self._failures:
                self._apply_due_failures()
            if self.fast_path:
                assert self._fast is not None
                stop = self.ground.contact_radius if self.ground is not None else 0.0
                # Inputs are constant inside one kernel call: stop at the next gust update or failure.
                chunk = 1 if gusts is not None else remaining
                if self._failures:
                    chunk = min(chunk, self._failures[0][0] - self._k)
                # The kernel stops early after touchdown or fuel-out so the checks below see that step.
                k = self._fast.advance(y, y_prev, dt, chunk, stop_radius=stop)
                self._k += k
                remaining -= k
            else:
                np.copyto(y_prev, y)
                integ.step(dyn, self._k * dt, y, dt)
                self._k += 1
                remaining -= 1
            if gusts is not None:
                gusts.advance()  # the gust of the next step (one draw per step, whatever the path)
                self._update_wind()
            self._after_step()

    def adopt_step(self, y_before: np.ndarray, y_after: np.ndarray, k: int) -> None:
        """Take step ``k - 1 -> k`` computed elsewhere (the batched sweep core flies many flights in
        one compiled loop): the flat states before and after it; then the after-step checks run as
        for a step of this Simulation's own (touchdown interpolation and classification, fuel-out,
        parachute, stabiliser). Call it only while flying, with states of this scene."""
        np.copyto(self._y_prev, y_before)
        np.copyto(self.y, y_after)
        self._k = int(k)
        self._after_step()

    @property
    def scheduled_failures(self) -> list[tuple[int, int]]:
        """Thruster failures still to come as ``(step index, thruster)``, soonest first (a copy)."""
        return list(self._failures)

    @property
    def fast_kernel(self) -> fast.FastLander | None:
        """The compiled kernel's packed parameters for this scene (None when the scene has no fast path)."""
        return self._fast

    def advance_to(self, t: float) -> None:
        """Step until the clock reaches ``t`` [s] (to the step grid, never beyond by a whole step)."""
        n = math.ceil((t - self.t) / self.dt - 1e-9)
        if n > 0:
            self.step(n)

    def _after_step(self) -> None:
        y = self.y
        if self.ground is not None and self.ground.below(y[R_W]):
            self._touchdown()
            return
        if not self._fuel_out and self.inputs.throttles.size and y[FUEL] <= 0.0:
            self._fuel_out = True
            self.inputs.throttles[:] = 0.0
            self._emit(EventKind.FUEL_EMPTY, "out of fuel: throttles forced to 0", {})
        if self.parachute is not None and self.parachute.status is ChuteStatus.DEPLOYED:
            drag = self.parachute.drag_magnitude(self.dynamics.fill_context(y))
            if drag > self.parachute.max_drag:
                self.parachute.status = ChuteStatus.LOST
                self._emit(EventKind.PARACHUTE_LOST, f"parachute torn off by {drag:.0f} N of drag", {"drag": drag})
        if self.stabiliser:
            stabilise(y, self.scene.attitude)
        self._check_gimbal()

    def _touchdown(self) -> None:
        """Interpolate to the impact instant inside the last step, classify, freeze."""
        g, y, y0 = self.ground, self.y, self._y_prev
        assert g is not None
        s = g.impact_fraction(y0[R_W], y[R_W])
        y[:] = y0 + s * (y - y0)
        if self.scene.attitude == "quaternion":
            y[ATT] = rotation.quat_normalise(y[ATT])
        q = y[ATT] if self.scene.attitude == "quaternion" else rotation.euler_to_quat(y[EULER])
        td = g.classify(s, y[R_W], y[V_W], rotation.body_to_world(q, np.array([0.0, 0.0, 1.0])))
        y[V_W] = 0.0
        y[OMEGA_B] = 0.0
        self.inputs.throttles[:] = 0.0
        self.phase = Phase.CRASHED if td.crashed else Phase.LANDED
        t_impact = (self._k - 1 + s) * self.dt
        # Appended keys only: readers index the first three.
        values = {"t_impact": t_impact, "descent_rate": td.descent_rate, "ground_speed": td.ground_speed,
                  "tilt_deg": math.degrees(td.tilt), "fuel_left": float(y[FUEL])}
        kind = {"safe": EventKind.LANDED, "hard": EventKind.HARD_LANDING}.get(td.classification, EventKind.CRASHED)
        detail = (f"{kind.value} at t = {t_impact:.3f} s ({td.classification}): descent rate {td.descent_rate:.2f} m/s, "
                  f"ground speed {td.ground_speed:.2f} m/s, tilt {math.degrees(td.tilt):.2f} deg, fuel left {float(y[FUEL]):.2f} kg")
        self._emit(kind, detail, values, t=t_impact)

    def _check_gimbal(self) -> None:
        """Warn once on entering the near-lock region of the Euler angles (Euler mode only)."""
        if self.scene.attitude != "euler":
            return
        near = rotation.near_gimbal_lock(self.y[EULER], self.scene.gimbal_threshold)
        if near and not self._near_lock:
            st = abs(math.sin(self.y[7]))
            self._emit(
                EventKind.GIMBAL_LOCK,
                f"Euler angles near gimbal lock: |sin theta| = {st:.3g} < {self.scene.gimbal_threshold:g}; "
                "eq 5 is ill-conditioned and the angles may jump",
                {"sin_theta": st},
            )
        self._near_lock = near

    def _emit(self, kind: EventKind, detail: str, values: dict[str, float], t: float | None = None) -> None:
        self._events.append(Event(kind, self.t if t is None else t, detail, values))

    def drain_events(self) -> list[Event]:
        """Events since the last call, oldest first."""
        ev, self._events = self._events, []
        return ev

    # --- reading ---------------------------------------------------------------

    def state(self) -> StateView:
        """A read-only copy of the current state (quaternion and Euler angles both filled in)."""
        y = self.y
        if self.scene.attitude == "quaternion":
            q = y[ATT].copy()
            E = rotation.quat_to_euler(q)
        else:
            E = y[EULER].copy()
            q = rotation.euler_to_quat(E)
        return StateView(self.t, y[R_W].copy(), y[V_W].copy(), q, E, y[OMEGA_B].copy(), float(y[FUEL]))

    @property
    def throttles(self) -> np.ndarray:
        """The throttles in force (a copy)."""
        return self.inputs.throttles.copy()

    def derived(self) -> Derived:
        """Altitude, climb rate, ground speed, mass, energy, angular momentum, Euler angles, gimbal flag."""
        y, dyn = self.y, self.dynamics
        r, v, w = y[R_W], y[V_W], y[OMEGA_B]
        rn = float(np.linalg.norm(r))
        rhat = r / rn if rn > 0.0 else np.zeros(3)
        climb = float(v @ rhat)
        ground_speed = float(np.linalg.norm(v - climb * rhat))
        mass = dyn.vehicle.mass(float(y[FUEL]))
        R = dyn.rotation_matrix(y)
        A, B, C = dyn.inertia(float(y[FUEL]))
        ke = kinetic_energy(A, B, C, w) + (0.5 * mass * float(v @ v) if dyn.translation else 0.0)
        pe = sum(m.potential(r, R, mass) for m in dyn.models if hasattr(m, "potential"))
        L_W = R.T @ np.array([A * w[0], B * w[1], C * w[2]])
        if self.scene.attitude == "quaternion":
            E = rotation.quat_to_euler(y[ATT])
            qerr = math.sqrt(float(y[ATT] @ y[ATT])) - 1.0
        else:
            E = y[EULER].copy()
            qerr = 0.0
        return Derived(
            altitude=rn - dyn.planet_radius,
            climb_rate=climb,
            ground_speed=ground_speed,
            mass=mass,
            kinetic_energy=ke,
            potential_energy=float(pe),
            energy=ke + float(pe),
            angular_momentum_W=L_W,
            euler=E,
            gimbal_lock=rotation.near_gimbal_lock(E, self.scene.gimbal_threshold),
            quat_norm_error=qerr,
        )

    # --- determinism -----------------------------------------------------------

    def snapshot(self) -> Snapshot:
        """A copy of everything that determines the future (state, clock, inputs, phase, model state)."""
        return Snapshot(
            y=self.y.copy(),
            k=self._k,
            throttles=self.inputs.throttles.copy(),
            wind_W=self.inputs.wind_W.copy(),
            phase=self.phase,
            chute=None if self.parachute is None else self.parachute.status,
            stabiliser=self.stabiliser,
            near_lock=self._near_lock,
            fuel_out=self._fuel_out,
            integrator=copy.deepcopy(self.integrator),
            mean_wind_W=self._mean_wind_W.copy(),
            gusts=None if self.gusts is None else self.gusts.get_state(),
            failed=self._failed.copy(),
        )

    def restore(self, snap: Snapshot) -> None:
        """Return bit-exactly to a :meth:`snapshot` of this simulation."""
        np.copyto(self.y, snap.y)
        self._k = snap.k
        self.inputs.throttles[:] = snap.throttles
        self.inputs.wind_W[:] = snap.wind_W
        self.phase = snap.phase
        if self.parachute is not None and snap.chute is not None:
            self.parachute.status = snap.chute
        self.stabiliser = snap.stabiliser
        self._near_lock = snap.near_lock
        self._fuel_out = snap.fuel_out
        self.integrator = copy.deepcopy(snap.integrator)  # internal state, e.g. the adaptive step size
        if snap.mean_wind_W is not None:
            self._mean_wind_W[:] = snap.mean_wind_W
        if self.gusts is not None and snap.gusts is not None:
            self.gusts.set_state(snap.gusts)
        if snap.failed is not None:
            self._failed[:] = snap.failed
        self._schedule_failures()
        self.inputs.wind_W[:] = snap.wind_W
