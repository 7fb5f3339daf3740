"""Hand one dispersed case to the normal ``lander fly`` path (:mod:`lander_tools.launcher`).

The launcher flies a *scene file* plus a timeline, so a case becomes: a scene YAML (the nominal
scene's file with the dispersed ``initial`` block) and timeline actions (demand altitude at 0 and
at the step time, the wind of every control period). Vehicle dispersions (mass, inertia, thrust
errors) and thruster failures have no equivalent there yet: such cases are refused, naming them.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lander_sim.physics.state import ATT, FUEL, OMEGA_B, R_W, V_W
from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.flight import apply_case, base_demand_altitude, nominal_scene, wind_schedule
from lander_tools.sweep.spec import SweepSpec


class NotRepresentable(ValueError):
    """The case uses a dispersion the ROS path cannot carry yet (the message names it)."""


def scene_file_for_case(spec: SweepSpec, index: int, folder: Path) -> Path:
    """Write the dispersed scene (initial state only) as YAML into ``folder``; return its path."""
    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    bad = [name for name, on in (
        ("mass_error", case.mass_error != 0.0), ("inertia_error", case.inertia_error != 0.0),
        ("thrust_error", any(e != 0.0 for e in case.thrust_error)), ("thruster_failure", case.failed_thruster >= 0),
    ) if on]
    if bad:
        raise NotRepresentable(
            f"flight {index} uses dispersions.{', dispersions.'.join(bad)}, which the ROS path "
            "(scene file + timeline) cannot carry yet; --replay without --record flies it core-only"
        )
    if scene0.attitude != "quaternion" or scene0.source is None:
        raise NotRepresentable(f"scene {scene0.name!r}: only quaternion-mode packaged scene files are supported")
    y = apply_case(scene0, case).initial_state
    data = yaml.safe_load(Path(scene0.source).read_text())
    data["name"] = f"{scene0.name}-sweep-{spec.seed}-{index}"
    data["aliases"] = []
    data["initial"] = {
        "position_W": [float(x) for x in y[R_W]],
        "velocity_W": [float(x) for x in y[V_W]],
        "attitude": {"quaternion": [float(x) for x in y[ATT]]},
        "omega_B": [float(x) for x in y[OMEGA_B]],
        "fuel": float(y[FUEL]),
    }
    path = folder / f"{data['name']}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def plan_for_case(spec: SweepSpec, controller_index: int, index: int, folder: Path, record: Path | None) -> Any:
    """A :class:`lander_tools.launcher.FlightPlan` flying case ``index`` in lockstep, as fast as possible."""
    from lander_tools.launcher import Action, FlightPlan

    scene0 = nominal_scene(spec)
    case = draw_case(spec, index, scene0.vehicle.n_thrusters)
    scene_path = scene_file_for_case(spec, index, folder)
    period = scene0.dt if spec.control_rate is None else 1.0 / spec.control_rate
    n = int(math.floor(spec.end.duration / period + 1e-9))
    h0 = base_demand_altitude(scene0)
    timeline = [Action(0.0, "demand_altitude", max(0.0, h0))]
    if case.demand_step:
        timeline.append(Action(spec.end.demand_step_time, "demand_altitude", max(0.0, h0 + case.demand_step)))
    winds = wind_schedule(scene0, case, spec.end.gust_time_constant, period, n)
    if winds is not None:
        constant = bool(np.all(winds == winds[0]))
        for k in range(1 if constant else n):
            timeline.append(Action(k * period, "wind", [float(w) for w in winds[k]]))
    choice = spec.controllers[controller_index]
    return FlightPlan(
        scene=str(scene_path), controller=choice.name, controller_params=dict(choice.params),
        duration=spec.end.duration, speed=0.0, lockstep=True, record=record,
        timeline=sorted(timeline, key=lambda a: a.t),
        meta={"sweep": spec.name, "seed": str(spec.seed), "flight": str(index), "controller": choice.label},
    )
