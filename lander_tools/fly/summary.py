"""The flight summary ``lander fly`` prints: how it ended, the last state, the touchdown's figures,
the lockstep and bag checks."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from lander_ros.flight_span import lockstep_warning
from lander_tools.fly.plan import FlightResult
from lander_tools.metrics_fit import SceneFacts, altitude_applies, fuel_applies
from lander_tools.sweep.metrics import altitude_and_tilt


def final_state(msg: Any, facts: SceneFacts | None = None) -> dict[str, float]:
    """What a pilot reads off the last LanderState: altitude [m], climb rate [m/s], ground speed
    [m/s], fuel [kg] and the tilt [deg] of the body z axis from the local vertical (the message's
    orientation components are the core's quaternion, lander_sim.ros.convert). NaN where a figure
    does not apply (lander_tools.metrics_fit, the rules ``lander analyse`` follows): the figures of
    flight over a surface on a fixed pivot (the rotor scenes, position r = 0, no local vertical)
    and, by the scene's ``facts``, in free space; fuel on a vehicle without thrusters."""
    o, p = msg.orientation, msg.position
    r = np.array([p.x, p.y, p.z])
    altitude, tilt = altitude_and_tilt(r, np.array([o.w, o.x, o.y, o.z]))
    over_surface = altitude_applies(r, facts) and math.isfinite(altitude)
    return {
        "altitude": float(msg.altitude) if over_surface else math.nan,
        "climb_rate": float(msg.climb_rate) if over_surface else math.nan,
        "ground_speed": float(msg.ground_speed) if over_surface else math.nan,
        "fuel": float(msg.fuel_mass) if fuel_applies(len(msg.throttles)) else math.nan,
        "tilt_deg": math.degrees(tilt) if over_surface else math.nan,
    }


def _figure(value: float, fmt: str, unit: str) -> str:
    return f"{value:{fmt}} {unit}" if math.isfinite(value) else "n/a"


def summary(result: FlightResult) -> str:
    """The flight summary ``lander fly`` prints: every figure named, with its unit; "n/a" where a
    figure does not apply (no touchdown in an orbit, no altitude or tilt on a fixed pivot or in free space); the
    controller and the gains in force as the autopilot last reported them."""
    rtf = result.sim_time / result.wall_time if result.wall_time > 0 else 0.0
    lines = [
        f"flight ended: {result.outcome} at sim time t = {result.sim_time:.2f} s "
        f"({result.states} states; {result.wall_time:.1f} s wall time, real-time factor {rtf:.1f}x), "
        f"exit code {result.exit_code}"
    ]
    if result.message:
        lines.append(f"  {result.message}")
    f = result.final
    if f:
        lines.append(
            f"  last state: altitude {_figure(f['altitude'], '.2f', 'm')}, "
            f"climb rate {_figure(f['climb_rate'], '+.3f', 'm/s')}, "
            f"ground speed {_figure(f['ground_speed'], '.3f', 'm/s')}, tilt {_figure(f['tilt_deg'], '.2f', 'deg')}, "
            f"fuel {_figure(f['fuel'], '.2f', 'kg')}"
        )
    # Touchdown figures come from the LANDED/CRASHED event's own named values (the core's
    # touchdown classification), never from the last state.
    td = result.touchdown
    if td:
        figures = [f"descent rate {_figure(td.get('descent_rate', math.nan), '.2f', 'm/s')}",
                   f"ground speed {_figure(td.get('ground_speed', math.nan), '.2f', 'm/s')}"]
        units = {"tilt_deg": ("tilt", ".2f", "deg"), "fuel_left": ("fuel left", ".2f", "kg")}
        figures += [f"{units[k][0]} {_figure(v, units[k][1], units[k][2])}" if k in units else f"{k} {v:.6g} (SI)"
                    for k, v in td.items() if k not in ("descent_rate", "ground_speed", "t_impact")]
        if result.touchdown_class:
            figures.append(f"{result.touchdown_class} (against the scene's touchdown limits)")
        lines.append(f"  touchdown at t = {_figure(td.get('t_impact', math.nan), '.3f', 's')}: " + ", ".join(figures))
    elif f:
        lines.append("  touchdown: n/a (none in this flight)")
    if result.controller:
        gains = f"gains in force {result.gains}" if result.gains else "no gains named by the law"
        lines.append(f"  controller {result.controller!r}: {gains}")
    warning = lockstep_warning(result.lockstep_timeouts)
    if warning:
        lines.append(f"  lockstep: {warning}")
    if result.bag is not None:
        lines.append(f"  bag: {result.bag} ({sum(result.counts.values())} messages; {result.bag_check})")
    return "\n".join(lines)
