"""The batched core of a sweep: many dispersed flights advanced together by one compiled loop.

Used whenever every controller of the spec has a compiled form
(:func:`~lander_autopilot.controllers.compiled.compiled_form`) and the scene fits the compiled
fast path (:func:`lander_sim.fast.unsupported_reason`, no stabiliser); :func:`unsupported_reason`
says why not otherwise, and the sweep then flies per flight (:func:`~.flight.fly_task`).

Each flight is set up exactly as the per-flight path sets it up: its case
(:func:`~.dispersion.draw_case`), its scene (:func:`~.case_scene.flown_scene`) and a
:class:`~lander_sim.simulation.Simulation` of it, from which the packed model parameters, the
initial state, the scheduled failures, the ground and the gust process are read; the gust process's
own generator then draws the normals the flight will use, in the order the Simulation would draw
them (three per physics step), so the gusts are the same numbers. The compiled loop
(:func:`~.batched_kernel.fly_flights`) returns the samples of :class:`~.metrics.Samples`, and the row
is made by the same :func:`~.flight.make_row`. A touchdown is handed back to the flight's
Simulation (its own interpolation and classification); a flight the loop cannot finish (throttles
the Simulation would refuse) is re-flown per flight, so its error row is the per-flight one.

Memory is bounded by flying in chunks of ``chunk`` flights.
"""
from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_tools.sweep import batched_kernel as bk
from lander_tools.sweep.case_scene import flown_scene, nominal_scene
from lander_tools.sweep.dispersion import FlightCase, draw_case
from lander_tools.sweep.flight import (
    _controller,
    _touchdown_speed,
    control_period,
    demand_schedule,
    fly_task,
    make_row,
)
from lander_tools.sweep.metrics import Samples, altitude_and_tilt
from lander_tools.sweep.spec import SweepSpec

__all__ = ["DEFAULT_CHUNK", "chunks", "fly_chunk", "fly_compiled", "laws_of", "unsupported_reason"]

#: Flights per chunk: about 50 kB each for a 60 s flight at 10 Hz (samples, gust normals, Simulation).
DEFAULT_CHUNK = 1000


def laws_of(spec: SweepSpec) -> list[Any] | None:
    """The compiled form of each controller of the spec (built on the nominal vehicle), or None."""
    from lander_autopilot.controllers.compiled import compiled_form

    vehicle = nominal_scene(spec).vehicle
    laws = [compiled_form(_controller(spec, ci, vehicle)) for ci in range(len(spec.controllers))]
    return None if any(law is None for law in laws) else laws


def unsupported_reason(spec: SweepSpec) -> str | None:
    """Why the spec cannot fly on the batched core (None if it can)."""
    from lander_autopilot.controllers.compiled import compiled_form
    from lander_sim import fast

    if not bk.HAVE_NUMBA:
        return "numba is not installed"
    scene = nominal_scene(spec)
    why = fast.unsupported_reason(scene)
    if why is not None:
        return f"scene {scene.name!r}: {why}"
    if scene.stabiliser:
        return f"scene {scene.name!r} has the stabiliser on (the compiled loop has none)"
    for ci, choice in enumerate(spec.controllers):
        if compiled_form(_controller(spec, ci, scene.vehicle)) is None:
            return f"controller {choice.label!r} has no compiled form"
    return None


@dataclass
class _Flight:
    """One flight's set-up (the per-flight path's objects, kept for touchdown and fallback)."""

    index: int
    case: FlightCase
    sim: Any
    demand: tuple[float, float, float]  # before [m], after [m], step time [s]


def _setup(spec: SweepSpec, index: int, n_thrusters: int) -> _Flight:
    from lander_sim.simulation import Simulation

    case = draw_case(spec, index, n_thrusters)
    sim = Simulation(flown_scene(spec, case))
    return _Flight(index, case, sim, demand_schedule(spec, nominal_scene(spec), case))


def _pack(flights: list[_Flight], n_steps: int) -> dict[str, np.ndarray]:
    """Arrays over flights for :func:`~.batched_kernel.fly_flights` (see its docstring)."""
    from lander_autopilot.controllers.base import Demand
    from lander_autopilot.controllers.compiled import N_DEMAND, demand_array

    F = len(flights)
    n = flights[0].sim.scene.vehicle.n_thrusters
    n_fail = max([len(f.sim.scheduled_failures) for f in flights] + [1])
    a: dict[str, np.ndarray] = {
        "y0": np.zeros((F, 14)), "kparams": np.zeros((F, flights[0].sim.fast_kernel.params.size)),
        "force": np.zeros((F, n, 3)), "torque": np.zeros((F, n, 3)), "burn": np.zeros((F, n)),
        "mean_wind": np.zeros((F, 3)), "gust_ab": np.zeros((F, 3)), "gust_g0": np.zeros((F, 3)),
        "gust_w": np.zeros((F, n_steps, 3)), "fail_step": np.full((F, n_fail), -1, dtype=np.int64),
        "fail_thruster": np.zeros((F, n_fail), dtype=np.int64), "d_before": np.zeros((F, N_DEMAND)),
        "d_after": np.zeros((F, N_DEMAND)), "t_change": np.zeros(F),
    }
    for f, fl in enumerate(flights):
        sim = fl.sim
        fk = sim.fast_kernel
        a["y0"][f] = sim.y
        a["kparams"][f] = fk.params
        a["force"][f], a["torque"][f], a["burn"][f] = fk.force, fk.torque, fk.burn
        a["mean_wind"][f] = sim.mean_wind_W
        g = sim.gusts
        if g is not None:
            a["gust_ab"][f] = (1.0, g.a, g.b)
            a["gust_g0"][f] = g.gust_W
            # The normals GustProcess.advance would draw, three per step, from the same generator
            # (a copy: the Simulation stays at its start for a touchdown hand-back).
            rng = np.random.Generator(type(g.rng.bit_generator)())
            rng.bit_generator.state = g.rng.bit_generator.state
            rng.standard_normal(out=a["gust_w"][f])
        for q, (step, thruster) in enumerate(sim.scheduled_failures):
            a["fail_step"][f, q], a["fail_thruster"][f, q] = step, thruster
        before, after, t_change = fl.demand
        d0, d1 = Demand(altitude=before), Demand(altitude=after)
        a["d_before"][f] = demand_array(d0.altitude, d0.attitude, d0.omega_B)
        a["d_after"][f] = demand_array(d1.altitude, d1.attitude, d1.omega_B)
        a["t_change"][f] = t_change
    return a


def _finish_touchdown(fl: _Flight, out: dict[str, np.ndarray], f: int) -> tuple[float, dict[str, Any], float, float, float]:
    """Hand the touchdown step to the flight's Simulation: ``(speed, figures, altitude error, tilt, fuel)``
    of the interpolated state, as the per-flight loop sees it."""
    sim = fl.sim
    sim.drain_events()
    # The Simulation's own after-step checks: touchdown interpolation, classification, event.
    sim.adopt_step(out["y_prev_last"][f], out["y_last"][f], int(out["k_last"][f]))
    speed, figures = _touchdown_speed(sim, out["v_before"][f].copy())
    st = sim.state()
    h, tilt = altitude_and_tilt(st.r_W, st.q)
    return speed, figures, h, tilt, float(st.fuel)


def fly_chunk(spec: SweepSpec, indices: Sequence[int], laws: list[Any] | None = None,
              parallel: bool = False) -> list[dict[str, Any]]:
    """Rows of flights ``indices`` for every controller, flown on the batched core; ``parallel``
    runs the compiled loop over the flights on numba's threads (the sweep runner uses processes
    instead: the per-flight set-up is Python)."""
    laws = laws if laws is not None else laws_of(spec)
    if laws is None:
        raise ValueError("fly_chunk: a controller of the spec has no compiled form (use the per-flight path)")
    scene0 = nominal_scene(spec)
    n_sub, period = control_period(spec, scene0.dt)
    n_ctrl = int(math.floor(spec.end.duration / period + 1e-9))
    flights: list[_Flight] = []
    rows: list[dict[str, Any]] = []
    broken: list[int] = []
    for i in indices:
        try:
            flights.append(_setup(spec, i, scene0.vehicle.n_thrusters))
        except Exception:  # noqa: BLE001 - the per-flight path makes the error row
            broken.append(i)
    if flights:
        inputs = _pack(flights, n_ctrl * n_sub)
        stop = flights[0].sim.ground.contact_radius if flights[0].sim.ground is not None else 0.0
        for ci, law in enumerate(laws):
            params, K = law.pack()
            out = bk.fly_flights(inputs, params, K, n_ctrl, n_sub, period, flights[0].sim.dt, stop, parallel)
            for f, fl in enumerate(flights):
                rows.append(_row(spec, ci, fl, out, f, period))
    for i in broken:
        rows.extend(fly_task(spec, ci, i) for ci in range(len(spec.controllers)))
    rows.sort(key=lambda r: (r["index"], r["controller_index"]))
    return rows


def _row(spec: SweepSpec, ci: int, fl: _Flight, out: dict[str, np.ndarray], f: int, period: float) -> dict[str, Any]:
    term = int(out["terminal"][f])
    if term == bk.TERM_ERROR:
        return fly_task(spec, ci, fl.index)
    ns = int(out["n_samples"][f])
    err, tilt = out["err"][f, :ns].copy(), out["tilt"][f, :ns].copy()
    rate = out["rate"][f, :ns].copy()
    fuel_end = float(out["fuel"][f, 1])
    before, after, t_change = fl.demand
    speed, figures, terminal = math.nan, {}, "ok"
    if term == bk.TERM_DIVERGED:
        terminal, fuel_end = "diverged", math.nan
    elif term == bk.TERM_TOUCHDOWN:
        if fl.sim.phase.name != "FLYING":  # handed a touchdown already (another controller): start afresh
            fl.sim.reset()
        speed, figures, h, tilt_last, fuel_end = _finish_touchdown(fl, out, f)
        t_last = (ns - 1) * period
        err[-1] = h - (after if t_last >= t_change else before)
        tilt[-1], rate[-1] = tilt_last, 0.0
        terminal = "crashed" if fl.sim.phase.name == "CRASHED" else "landed"
    samples = Samples(
        t=np.arange(ns) * period, altitude_error=err, tilt=tilt, body_rate=rate,
        fuel_start=float(out["fuel"][f, 0]), fuel_end=fuel_end, saturated_updates=int(out["sats"][f]), period=period,
        touchdown_speed=speed, terminal=terminal, t_change=t_change, touchdown=figures,
    )
    return make_row(spec, ci, fl.index, fl.case, samples)


def chunks(indices: Sequence[int], size: int) -> Iterator[list[int]]:
    """``indices`` in consecutive chunks of at most ``size``."""
    idx = list(indices)
    for k in range(0, len(idx), max(1, size)):
        yield idx[k:k + size]


def fly_compiled(sim: Any, law: Any, demand_altitude: float, duration: float, n_sub: int = 1, copies: int = 1,
                 record_states: bool = False, parallel: bool = False) -> dict[str, np.ndarray]:
    """The compiled closed loop of one flight: ``sim``'s scene from its current start, the law
    ``law`` (:class:`~lander_autopilot.controllers.compiled.CompiledLaw`) at a constant demand
    altitude [m], every ``n_sub`` physics steps, for ``duration`` [s]. ``copies`` flies the same
    flight that many times in one call (for timing). Returns :func:`~.batched_kernel.fly_flights`'s arrays."""
    period = n_sub * sim.dt
    n_ctrl = int(math.floor(duration / period + 1e-9))
    inputs = _pack([_Flight(-1, FlightCase(-1, 0), sim, (demand_altitude, demand_altitude, 0.0))] * copies, n_ctrl * n_sub)
    params, K = law.pack()
    stop = sim.ground.contact_radius if sim.ground is not None else 0.0
    return bk.fly_flights(inputs, params, K, n_ctrl, n_sub, period, sim.dt, stop, parallel, record_states)
