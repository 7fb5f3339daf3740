"""The flown powered descent of a recorded de-orbit flight against the fuel-optimal reference.

The de-orbit flights' fuel yardstick (docs/deorbit.md, "The fuel yardstick"): from the state at the handover to the
powered descent, the minimum fuel any thrust history within the vehicle's limits needs to come to
rest at the demand altitude (:func:`lander_autopilot.guidance.fuel_optimal.solve`, lossless
convexification with the chute's drag). ``lander analyse BAG --reference`` prints the flown fuel
against it and plots the flown trajectory over it. No rclpy: bag samples in (:class:`Flight`),
numbers and a figure out.

From the bag (what the nodes publish, docs/deorbit.md "Phases"):

* The handover: the first ``MODE_CHANGED`` event on ``/lander/events`` into ``powered-descent``
  (the de-orbit controllers ``deorbit`` and ``deorbit-mpc``; the autopilot's detail reads
  ``controller 'deorbit' mode 'parachute' -> 'powered-descent'``). Its stamp is the sim time of the
  state the law answered, so the state it was decided on is the first ``/lander/state`` sample at
  or after that time (the same sample in lockstep; at any speed, the nearest later one).
  Position, velocity, fuel and the chute flag come from that sample (``/lander/state`` carries
  them all, at the sim's publish rate; the odometry is not needed).
* The end of the powered phase: the first ``MODE_CHANGED`` into ``hover`` after it, and the first
  state at or after it. Fuel flown = fuel at the handover sample - fuel at that sample (as
  ``bench/deorbit_fuel.py`` counts it: the phase from its first step to the first step of the hover).
* The vehicle: the scene named in the bag's metadata (``scene``, written by ``lander fly --record``
  and ``lander record --whole-flight``). The demand altitude: the one in force at the handover as
  ``/autopilot/status`` reports it, else the scene's ``autopilot.demand_altitude``.

The problem is :func:`lander_autopilot.controllers.deorbit_mpc.handover_problem` (full axial thrust,
tilt limit 0.7 rad, sphere drag and, if the chute is out at the handover, the canopy's) solved with
60 nodes, exactly as ``bench/deorbit_fuel.py`` does (its ``optimum``). The reference's times are
offset to the handover sample's.

The optimum is a lower bound up to its own tolerances (fuel_optimal: the fuel settles to 1e-3 of the
burn, the linearised drag matches the true drag to 1e-2 m/s^2, ~0.3 % of the burn; the node count's
discretisation changes it by ~2e-4 between 30 and 60 nodes): :data:`OPTIMUM_TOLERANCE`. A ratio
under ``1 - OPTIMUM_TOLERANCE`` means a wrong state, vehicle or demand, not a law better than optimal.
"""
from __future__ import annotations

import dataclasses
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lander_sim.physics import constants as c
from lander_tools import plotstyle as ps
from lander_tools.analysis import Flight

#: FlightEvent.MODE_CHANGED (lander_interfaces/msg/FlightEvent.msg), as a plain int (no rclpy here).
EV_MODE_CHANGED = 11
POWERED, HOVER = "powered-descent", "hover"
#: Relative tolerance of the optimum as a lower bound (module docstring).
OPTIMUM_TOLERANCE = 5e-3
#: Nodes of the reference (bench/deorbit_fuel.py's ``optimum``).
STEPS = 60

_NEW_MODE = re.compile(r"->\s*'([^']*)'\s*$")


class OverlayError(ValueError):
    """The reference cannot be built for this bag (no scene, no demand, no feasible descent); one line."""


class NotApplicable(OverlayError):
    """The bag has no powered descent to measure (no handover event, or no state at or after it)."""


@dataclass(frozen=True)
class Handover:
    """The state the powered descent started from (SI units, world frame ``mars``)."""

    event_time: float  #: sim time of the MODE_CHANGED into powered-descent [s]
    index: int  #: its state sample in the flight
    t: float  #: that sample's sim time [s]
    r_W: np.ndarray
    v_W: np.ndarray
    fuel: float  #: [kg]
    altitude: float  #: [m]
    climb_rate: float  #: vertical speed, positive up [m/s]
    ground_speed: float  #: [m/s]
    chute_open: bool


@dataclass(frozen=True)
class Setup:
    """A flight's powered descent and the reference problem from its handover, not solved yet."""

    name: str
    scene: str
    controller: str
    demand_altitude: float  #: [m]
    handover: Handover
    hover_index: int | None  #: first state at or after the MODE_CHANGED into hover (None: not reached)
    hover_time: float | None  #: that sample's sim time [s]
    fuel_flown: float | None  #: [kg], None without a hover
    problem: Any  #: fuel_optimal.DescentProblem (local ENU frame at the handover, origin on the surface)
    frame: np.ndarray  #: rows: the local frame's axes in the world frame
    vehicle: Any  #: the scene's vehicle (thrusters for the flown thrust)


@dataclass(frozen=True)
class Overlay(Setup):
    """:class:`Setup` with the reference solved."""

    solution: Any  #: fuel_optimal.DescentSolution
    solve_wall: float  #: wall time of the solve [s]

    @property
    def fuel_optimum(self) -> float:
        return float(self.solution.fuel)

    @property
    def ratio(self) -> float | None:
        """Fuel flown / optimum (None without a hover)."""
        return None if self.fuel_flown is None else self.fuel_flown / self.fuel_optimum

    def summary(self) -> dict[str, Any]:
        """The numbers, SI units, JSON-ready (``lander analyse --reference --json``)."""
        h = self.handover
        return {
            "name": self.name, "scene": self.scene, "controller": self.controller,
            "demand_altitude": self.demand_altitude,
            "handover_event_time": h.event_time, "handover_time": h.t, "handover_altitude": h.altitude,
            "handover_climb_rate": h.climb_rate, "handover_ground_speed": h.ground_speed,
            "handover_fuel": h.fuel, "chute_open": h.chute_open,
            "hover_time": self.hover_time,
            "powered_duration": None if self.hover_time is None else self.hover_time - h.t,
            "fuel_flown": self.fuel_flown, "fuel_optimum": self.fuel_optimum, "ratio": self.ratio,
            "optimum_final_time": float(self.solution.final_time), "solve_count": int(self.solution.solve_count),
            "solve_wall_time": self.solve_wall,
        }

    def lines(self) -> list[str]:
        """The summary as text for the terminal."""
        h = self.handover
        at = f"t = {h.t:.3f} s" + ("" if abs(h.t - h.event_time) < 1e-6 else f" (event at {h.event_time:.3f} s)")
        out = [
            f"fuel-optimal reference, {self.name} (scene {self.scene}, controller {self.controller}):",
            f"  handover {at}: altitude {h.altitude:.1f} m, vertical speed {h.climb_rate:.2f} m/s, "
            f"ground speed {h.ground_speed:.2f} m/s, fuel {h.fuel:.3f} kg, chute {'open' if h.chute_open else 'not out'}, "
            f"demand {self.demand_altitude:g} m",
        ]
        if self.hover_time is None or self.fuel_flown is None:
            out.append("  flown: no MODE_CHANGED into 'hover' after the handover in the bag: no flown fuel to compare")
        else:
            out.append(f"  flown: {self.hover_time - h.t:.2f} s to the hover (t = {self.hover_time:.3f} s), "
                       f"fuel {self.fuel_flown:.3f} kg")
        out.append(f"  optimum: fuel {self.fuel_optimum:.3f} kg, final time {self.solution.final_time:.2f} s "
                   f"({self.solution.solve_count} convex solves, {self.solve_wall:.1f} s)")
        if self.ratio is not None:
            note = ""
            if self.ratio < 1.0 - OPTIMUM_TOLERANCE:
                note = (f"  (below the optimum by more than its tolerance {OPTIMUM_TOLERANCE:g}: check the bag's "
                        f"scene and demand)")
            out.append(f"  flown / optimum: {self.ratio:.4f}{note}")
        return out


# --- from the bag -----------------------------------------------------------------------------


def mode_changes(flight: Flight) -> list[tuple[float, str]]:
    """``(sim time, new mode)`` of every MODE_CHANGED event of the flight, in time order."""
    out = []
    for t, kind, detail, _ in flight.events:
        if kind != EV_MODE_CHANGED:
            continue
        m = _NEW_MODE.search(detail)
        new = m.group(1) if m else detail.rsplit("->", 1)[-1].strip().strip("'\"")
        out.append((float(t), new))
    return sorted(out, key=lambda e: e[0])


def _sample_at_or_after(flight: Flight, t: float) -> int | None:
    k = int(np.searchsorted(flight.t, t - 1e-9, side="left"))
    return k if k < len(flight.t) else None


def handover(flight: Flight) -> tuple[Handover, int | None, float | None]:
    """The handover state, and the hover's state sample index and time (None: no hover after it).

    Raises :class:`NotApplicable` when the flight has no MODE_CHANGED into powered-descent or no
    state at or after it."""
    if not len(flight.t):
        raise NotApplicable("no /lander/state samples: no powered descent to measure")
    changes = [(t, m) for t, m in mode_changes(flight) if t >= flight.t[0] - 1e-9]
    powered = next((t for t, m in changes if m == POWERED), None)
    if powered is None:
        n = sum(1 for e in flight.events if e[1] == EV_MODE_CHANGED)
        raise NotApplicable(f"no MODE_CHANGED into {POWERED!r} on /lander/events ({n} mode changes, "
                            f"{len(flight.events)} events in the bag): no powered descent to measure (the de-orbit "
                            f"controllers deorbit and deorbit-mpc fly one)")
    k = _sample_at_or_after(flight, powered)
    if k is None:
        raise NotApplicable(f"the handover to {POWERED!r} at t = {powered:.3f} s has no /lander/state sample at or "
                            f"after it (the states end at t = {flight.t[-1]:.3f} s)")
    r, v = flight.r_W[k].astype(float), flight.v_W[k].astype(float)
    rn = float(np.linalg.norm(r))
    climb = float(v @ r) / rn
    ho = Handover(event_time=powered, index=k, t=float(flight.t[k]), r_W=r, v_W=v, fuel=float(flight.fuel[k]),
                  altitude=rn - c.MARS_RADIUS, climb_rate=climb,
                  ground_speed=float(np.linalg.norm(v - climb * r / rn)),  # as the simulator's readout
                  chute_open=bool(flight.parachute[k]) if len(flight.parachute) > k else True)
    hover = next((t for t, m in changes if m == HOVER and t >= powered), None)
    kh = None if hover is None else _sample_at_or_after(flight, hover)
    return ho, kh, None if kh is None else float(flight.t[kh])


def prepare(flight: Flight, scene: str | None = None) -> Setup:
    """The handover, the hover and the reference problem of ``flight`` (quick: no solve).

    ``scene``: a scene name or YAML path for a bag whose metadata names none (an MCAP cut short, e.g.
    a recorder killed mid-flight, has no ``metadata.yaml``); the bag's own ``scene`` wins.
    Raises :class:`NotApplicable` (no powered descent in the bag) or :class:`OverlayError` (no
    scene, no demand altitude, a handover state the problem refuses), each with a one-line message."""
    from lander_autopilot.controllers.deorbit_mpc import handover_problem
    from lander_autopilot.guidance.fuel_optimal import GuidanceError
    from lander_sim.scenes import load_scene

    ho, kh, t_hover = handover(flight)
    name = flight.meta.get("scene") or scene or ""
    if not name:
        raise OverlayError("the bag's metadata names no scene (lander fly --record and lander record --whole-flight "
                           "write it; a bag cut short has no metadata.yaml): give the flight's scene with --scene")
    try:
        sc = load_scene(name)
    except (ValueError, OSError) as exc:
        raise OverlayError(f"scene {name!r}: {' '.join(str(exc).split())}") from None
    demand = float(flight.demand_at(np.array([ho.t]))[0])
    if not math.isfinite(demand):
        if sc.autopilot is None or sc.autopilot.demand_altitude is None:
            raise OverlayError("no demand altitude: neither /autopilot/status nor /lander/demand_altitude in the bag, "
                               f"nor the autopilot section of scene {name!r}, gives one")
        demand = float(sc.autopilot.demand_altitude)
    try:
        problem, frame = handover_problem(sc.vehicle, ho.r_W, ho.v_W, ho.fuel, demand, chute_open=ho.chute_open)
    except GuidanceError as exc:
        raise OverlayError(f"no reference problem from the handover at t = {ho.t:.3f} s: {exc}") from None
    return Setup(name=flight.name, scene=name, controller=flight.meta.get("controller", "?"), demand_altitude=demand,
                 handover=ho, hover_index=kh, hover_time=t_hover,
                 fuel_flown=None if kh is None else ho.fuel - float(flight.fuel[kh]),
                 problem=problem, frame=frame, vehicle=sc.vehicle)


def solve_reference(setup: Setup, steps: int = STEPS) -> Overlay:
    """Solve the reference of ``setup`` (seconds: a convex programme per final time tried, ~40 of
    them); :class:`OverlayError` when no descent from the handover is feasible."""
    from lander_autopilot.guidance.fuel_optimal import GuidanceError, solve

    t0 = time.perf_counter()
    try:
        solution = solve(setup.problem, steps=steps)
    except GuidanceError as exc:
        raise OverlayError(f"no fuel-optimal reference from the handover at t = {setup.handover.t:.3f} s: "
                           f"{exc}") from None
    fields = {f.name: getattr(setup, f.name) for f in dataclasses.fields(Setup)}
    return Overlay(**fields, solution=solution, solve_wall=time.perf_counter() - t0)


def build(flight: Flight, steps: int = STEPS, scene: str | None = None) -> Overlay:
    """:func:`prepare` then :func:`solve_reference`."""
    return solve_reference(prepare(flight, scene), steps)


# --- the figure -------------------------------------------------------------------------------


def thrust_magnitude(flight: Flight, vehicle: Any) -> np.ndarray:
    """``|sum_i t_i T_max,i d_i|`` of each state's throttles [N] (enabled thrusters; the state's
    throttles are the command applied over the step that ends at the sample)."""
    thr = np.nan_to_num(np.atleast_2d(flight.throttles))
    force = np.zeros((len(flight.t), 3))
    for i, th in enumerate(vehicle.thrusters[: thr.shape[1]]):
        if th.enabled:
            force -= thr[:, i : i + 1] * th.max_thrust * np.asarray(th.direction_B, float)[None, :]
    return np.linalg.norm(force, axis=1)


def figure(flight: Flight, overlay: Overlay) -> Any:
    """Altitude, vertical speed, ground speed, thrust and fuel against sim time: the flown powered
    descent (and a margin either side) with the reference over it, offset to the handover sample."""
    plt = ps.pyplot()
    ho, sol = overlay.handover, overlay.solution
    end = max(overlay.hover_time if overlay.hover_time is not None else ho.t, ho.t + float(sol.final_time))
    margin = 0.3 * (end - ho.t)
    sel = (flight.t >= ho.t - margin) & (flight.t <= end + margin)
    t = flight.t[sel]
    r, v = flight.r_W[sel], flight.v_W[sel]
    rn = np.linalg.norm(r, axis=1)
    climb = np.einsum("ij,ij->i", v, r) / rn
    ground = np.linalg.norm(v - (climb / rn)[:, None] * r, axis=1)  # not sqrt(|v|^2 - climb^2): round-off
    thrust = thrust_magnitude(flight, overlay.vehicle)[sel]
    tr = ho.t + sol.t
    ref_ground = np.hypot(sol.velocity_L[:, 0], sol.velocity_L[:, 1])

    fig, axes = plt.subplots(5, 1, sharex=True, figsize=(8, 12), layout="constrained")
    flown, ref = ps.colour(0), ps.colour(1)
    panels = [
        ("altitude [m]", flight.altitude[sel], sol.position_L[:, 2]),
        ("vertical speed [m/s]", climb, sol.velocity_L[:, 2]),
        ("ground speed [m/s]", ground, ref_ground),
        ("thrust magnitude [N]", thrust, sol.thrust_magnitude),
        ("fuel [kg]", flight.fuel[sel], sol.mass - overlay.problem.limits.dry_mass),
    ]
    for ax, (label, y_flown, y_ref) in zip(axes, panels):
        # the state's throttles act over the step ending at the sample: held to the left
        ax.plot(t, y_flown, color=flown, drawstyle="steps-pre" if label.startswith("thrust") else "default")
        ax.plot(tr, y_ref, color=ref, ls="--")
        ax.axvline(ho.t, color="0.4", ls=":", lw=1.0)
        if overlay.hover_time is not None:
            ax.axvline(overlay.hover_time, color="0.4", ls="-.", lw=1.0)
        ax.set_ylabel(label)
        ax.set_xlabel("simulation time [s]")
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.grid(True)
    axes[0].axhline(overlay.demand_altitude, color="0.6", lw=0.8)
    axes[3].axhline(overlay.problem.limits.rho_max, color="0.6", lw=0.8)
    flown_text = "no hover in the bag" if overlay.fuel_flown is None else (
        f"flown {overlay.fuel_flown:.2f} kg, optimum {overlay.fuel_optimum:.2f} kg, ratio {overlay.ratio:.3f}")
    axes[0].set_title(f"{overlay.name} ({overlay.controller}): powered descent, {flown_text}", fontsize="medium")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=flown, label="flown"),
               Line2D([], [], color=ref, ls="--", label="fuel-optimal reference"),
               Line2D([], [], color="0.4", ls=":", label="handover (powered-descent)"),
               Line2D([], [], color="0.4", ls="-.", label="hover"),
               Line2D([], [], color="0.6", lw=0.8, label="demand altitude / thrust limit")]
    ps.legend_outside(fig, handles, [str(h.get_label()) for h in handles])
    return fig


def write_figure(flight: Flight, overlay: Overlay, path: str | Path) -> Path:
    """:func:`figure` to ``path`` (PNG); returns the path."""
    return ps.save(figure(flight, overlay), Path(path))
