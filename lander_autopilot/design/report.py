"""The design report of ``lander design SCENE``: matrices, controllability, gains and poles.

:func:`design_report` builds a JSON-able dict for the altitude model (eq 16), the attitude
model (eq 28) and the full translational + attitude model about the hover
(:mod:`.translational`: 12 states in the local ENU frame, seed 2 section 6); :func:`format_report`
prints it like seed 2's Octave scripts do.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lander_sim.physics.vehicle import Vehicle

from . import DesignError
from .altitude import altitude_model
from .attitude import UPRIGHT_EULER, attitude_model
from .controllability import controllability
from .gains import GainDesign, lqr, place_poles
from .translational import FULL_STATES, LOCAL_FRAME, full_model

#: Default closed-loop poles of the full model (12): translation slower than attitude, all distinct
#: (repeated poles beyond rank B = 4 would need place_varga, which is unreliable here).
FULL_POLES = (-0.4, -0.45, -0.5, -0.55, -0.6, -0.9, -1.0, -1.05, -1.1, -1.15, -1.2, -1.3)
#: LQR weights of the full model, Bryson's rule: 10 m of position, 1 m/s of velocity, 0.1 rad and
#: 0.1 rad/s of attitude, a throttle excursion of 0.1 per thruster.
FULL_Q = (0.01, 0.01, 0.01, 1.0, 1.0, 1.0, 100.0, 100.0, 100.0, 100.0, 100.0, 100.0)
FULL_R = 100.0

ATTITUDE_STATES = ("phi", "theta", "psi", "wx", "wy", "wz")
ALTITUDE_STATES = ("z", "z_dot")


def _poles_json(p: np.ndarray) -> list[list[float]]:
    """Complex poles as ``[re, im]`` pairs (JSON has no complex numbers)."""
    return [[float(z.real), float(z.imag)] for z in np.asarray(p, dtype=complex)]


def _model_section(
    A: np.ndarray, B: np.ndarray, states: tuple[str, ...], poles: list[complex], Q: np.ndarray, R: np.ndarray
) -> dict[str, Any]:
    ctrb = controllability(A, B)
    out: dict[str, Any] = {
        "states": list(states),
        "A": A.tolist(),
        "B": B.tolist(),
        "controllability_rank": ctrb.rank,
        "n_states": A.shape[0],
        "controllable": ctrb.controllable,
        # Clean rounding noise so exact directions (e.g. pure psi) print as such.
        "uncontrollable_basis": np.where(np.abs(ctrb.uncontrollable) < 1e-12, 0.0, ctrb.uncontrollable).T.tolist(),
        "open_loop_poles": _poles_json(np.linalg.eigvals(A)),
    }
    d: GainDesign = place_poles(A, B, poles)
    out["placement"] = {
        "method": d.method,
        "requested_poles": _poles_json(d.requested) if d.requested is not None else None,
        "K": d.K.tolist(),
        "closed_loop_poles": _poles_json(d.poles),
    }
    try:
        dl = lqr(A, B, Q, R)
        out["lqr"] = {"Q": Q.tolist(), "R": R.tolist(), "K": dl.K.tolist(), "closed_loop_poles": _poles_json(dl.poles)}
    except DesignError as exc:
        out["lqr"] = {"error": str(exc)}
    return out


def design_report(
    vehicle: Vehicle,
    fuel: float,
    altitude: float = 500.0,
    altitude_poles: tuple[complex, ...] = (-0.9, -1.1),
    attitude_poles: tuple[complex, ...] = (-1.0,) * 6,
    E_e: tuple[float, float, float] = UPRIGHT_EULER,
) -> dict[str, Any]:
    """Both models' ``A``, ``B``, controllability rank and uncontrollable basis (rows are state
    directions), pole-placement gain ``K`` and LQR gain with their closed-loop poles."""
    from ..controllers.combined import LQR_Q_ALTITUDE, LQR_Q_ATTITUDE, LQR_R_ALTITUDE, LQR_R_ATTITUDE

    alt = altitude_model(vehicle, fuel, altitude)
    att = attitude_model(vehicle, fuel, E_e)
    full = full_model(vehicle, fuel, altitude, E_e)
    return {
        "mass": alt.mass,
        "fuel": float(fuel),
        "altitude": {
            "demand_altitude": float(altitude),
            "T_v": alt.T_v,
            "hover_throttle": alt.t_e,
            **_model_section(
                alt.A, alt.B, ALTITUDE_STATES, list(altitude_poles), np.diag(LQR_Q_ALTITUDE), LQR_R_ALTITUDE * np.eye(1)
            ),
        },
        "attitude": {
            "demand_euler": [float(e) for e in E_e],
            "inertia": att.inertia.tolist(),
            "torque_arms": vehicle.torque_arms().tolist(),
            **_model_section(
                att.A,
                att.B,
                ATTITUDE_STATES,
                list(attitude_poles),
                np.diag(LQR_Q_ATTITUDE),
                LQR_R_ATTITUDE * np.eye(vehicle.n_thrusters),
            ),
        },
        "translational": {
            "frame": LOCAL_FRAME,
            "hover_thrust_acceleration": full.g,
            **_model_section(
                full.A, full.B, FULL_STATES, list(FULL_POLES), np.diag(FULL_Q), FULL_R * np.eye(vehicle.n_thrusters)
            ),
        },
    }


@dataclass(frozen=True)
class AxesRank:
    """One model a law controls that a vehicle's thrusters do not fully reach (:func:`uncontrollable_axes`)."""

    model: str  #: ``"altitude"`` (eq 16) or ``"attitude"`` (eq 28)
    rank: int  #: rank of eq 6's controllability matrix
    n_states: int
    #: States with a part in the uncontrollable subspace (the left null space of eq 6's ``P``), in
    #: the model's order: ``psi, wz`` for vertical thrusters (no torque about body z).
    states: tuple[str, ...]


def uncontrollable_axes(vehicle: Vehicle, fuel: float, models: tuple[str, ...],
                        E_e: tuple[float, float, float] = UPRIGHT_EULER) -> list[AxesRank]:
    """The models among ``models`` (``"altitude"``, ``"attitude"``; others are ignored) that the
    vehicle's enabled thrusters cannot control at the hover, each with its rank and the states
    its uncontrollable directions involve (a component above 1e-9 of a unit basis vector).

    Rank of eq 6's ``P = [B AB ... A^(n-1) B]`` (:func:`.controllability.controllability`), the
    attitude model linearised at ``E_e`` (upright by default). A vehicle with no upward thrust
    cannot hover: its altitude model is reported with rank 0. Plain numpy (no python-control)."""
    out: list[AxesRank] = []
    for model in models:
        states: tuple[str, ...]
        if model == "altitude":
            states = ALTITUDE_STATES
            try:
                alt = altitude_model(vehicle, fuel, 500.0)
            except DesignError:
                out.append(AxesRank(model, 0, len(states), states))
                continue
            A, B = alt.A, alt.B
        elif model == "attitude":
            states = ATTITUDE_STATES
            att = attitude_model(vehicle, fuel, E_e)
            A, B = att.A, att.B
        else:
            continue
        c = controllability(A, B)
        if c.controllable:
            continue
        involved = tuple(s for j, s in enumerate(states) if np.linalg.norm(c.uncontrollable[j, :]) > 1e-9)
        out.append(AxesRank(model, c.rank, A.shape[0], involved))
    return out


#: [-] entries under this fraction of the largest of their matrix (or pole set) are printed as 0:
#: the round-off of the linearisation and of the design (cos(pi/2) = 6.1e-17 in a rotation, the
#: 1e-16 left of a pole at the origin), far under the 5 digits printed. The JSON keeps every bit.
ROUNDOFF = 1e-12


def _shown(v: float, scale: float) -> float:
    """``v`` as printed: 0 (never -0) when it is round-off against ``scale``."""
    return 0.0 if abs(v) <= ROUNDOFF * scale else v


def _fmt_matrix(M: list[list[float]], indent: str = "    ") -> str:
    if not M:
        return indent + "(empty)"
    scale = max((abs(v) for row in M for v in row), default=0.0)
    return "\n".join(indent + " ".join(f"{_shown(v, scale):11.5g}" for v in row) for row in M)


def _fmt_poles(p: list[list[float]]) -> str:
    scale = max((abs(complex(re, im)) for re, im in p), default=0.0)
    shown = [(_shown(re, scale), _shown(im, scale)) for re, im in p]
    return ", ".join(f"{re:.6g}{im:+.3g}j" if abs(im) > 1e-9 else f"{re:.6g}" for re, im in shown)


def format_report(rep: dict[str, Any]) -> str:
    """Human-readable text of :func:`design_report`."""
    lines = [f"mass {rep['mass']:.6g} kg (fuel {rep['fuel']:.6g} kg)"]
    sections = (
        ("altitude", "Altitude model (eq 16)"),
        ("attitude", "Attitude model (eq 28)"),
        ("translational", "Translational + attitude model (local ENU frame, origin below the hover)"),
    )
    for key, title in sections:
        if key not in rep:
            continue
        s = rep[key]
        lines.append(f"\n== {title}: x = [{' '.join(s['states'])}]")
        if key == "altitude":
            lines.append(f"T_v = {s['T_v']:.6g} N, hover throttle t_e = {s['hover_throttle']:.6g} (eq 14)")
        lines += ["A =", _fmt_matrix(s["A"]), "B =", _fmt_matrix(s["B"])]
        lines.append(f"controllability matrix rank = {s['controllability_rank']} of {s['n_states']}")
        if s["uncontrollable_basis"]:
            lines.append("uncontrollable directions (rows, over " + " ".join(s["states"]) + "):")
            lines.append(_fmt_matrix(s["uncontrollable_basis"]))
        p = s["placement"]
        lines.append(f"pole placement ({p['method']}), requested poles {_fmt_poles(p['requested_poles'])}")
        lines += ["K =", _fmt_matrix(p["K"]), f"closed-loop poles: {_fmt_poles(p['closed_loop_poles'])}"]
        lq = s["lqr"]
        if "error" in lq:
            lines.append(f"LQR: {lq['error']}")
        else:
            lines += ["LQR K =", _fmt_matrix(lq["K"]), f"LQR closed-loop poles: {_fmt_poles(lq['closed_loop_poles'])}"]
    return "\n".join(lines)


# --- the sensors section (``lander design SCENE --sensors ...``) ------------------------------------


def sensors_report(vehicle: Vehicle, fuel: float, sensors: tuple[str, ...], altitude: float = 500.0,
                   E_e: tuple[float, float, float] = UPRIGHT_EULER) -> dict[str, Any]:
    """Observability of the altitude (eq 16), attitude (eq 28) and translational models for the
    sensor set (:mod:`.observability`), and for the altitude model, when its sensors observe it,
    the steady-state Kalman gain and the LQG closed loop with the separation check.

    Noise: the sensors' default parameters (:mod:`lander_sim.sensors`) at the hover: the
    altimeter's ``sigma = hypot(floor, fraction h)`` and the Doppler's floor, as densities
    ``R_N = sigma^2 / rate``; the process noise is the accelerometer's white-noise density on the
    vertical acceleration (the disturbance a filter propagating on the IMU sees).
    """
    from lander_sim.sensors.params import defaults
    from lander_sim.sensors.suite import SENSORS as SENSOR_TABLES

    from ..controllers.combined import LQR_Q_ALTITUDE, LQR_R_ALTITUDE
    from .gains import match_poles
    from .observability import lqg, observability, sensor_outputs

    alt = altitude_model(vehicle, fuel, altitude)
    att = attitude_model(vehicle, fuel, E_e)
    full = full_model(vehicle, fuel, altitude, E_e)
    models = (("altitude", alt.A, ALTITUDE_STATES), ("attitude", att.A, ATTITUDE_STATES),
              ("translational", full.A, FULL_STATES))
    linear = tuple(s for s in sensors if s != "accelerometer")  # its rows of C are zero (module .observability)
    out: dict[str, Any] = {"sensors": list(sensors)}
    for key, A, states in models:
        C = sensor_outputs(key, states, linear, 1).C
        obs = observability(A, C)
        out[key] = {"states": list(states), "outputs": list(sensor_outputs(key, states, linear, 1).labels),
                    "observability_rank": obs.rank, "n_states": A.shape[0],
                    "unobservable_basis": np.where(np.abs(obs.unobservable) < 1e-12, 0.0, obs.unobservable).T.tolist()}
    so = sensor_outputs("altitude", ALTITUDE_STATES, linear, 1)
    if observability(alt.A, so.C).observable:
        rates, sig = [], []
        for label in so.labels:
            if label == "z":
                v = defaults(SENSOR_TABLES["altimeter"][0])
                sig.append(float(np.hypot(v["noise_floor"], v["noise_fraction"] * altitude)))
            else:
                v = defaults(SENSOR_TABLES["doppler"][0])
                sig.append(float(v["noise_floor"]))
            rates.append(float(v["rate"]))
        R_N = np.diag(np.array(sig) ** 2 / np.array(rates))
        q_n = float(defaults(SENSOR_TABLES["imu"][0])["accel_noise_density"]) ** 2
        d = lqg(alt.A, alt.B, so.C, np.diag(LQR_Q_ALTITUDE), LQR_R_ALTITUDE * np.eye(1),
                np.array([[0.0], [1.0]]), np.array([[q_n]]), R_N)
        union = np.concatenate([d.regulator_poles, d.estimator_poles])
        out["altitude"]["kalman"] = {"R_N": R_N.tolist(), "Q_N": q_n, "L": d.L.tolist(),
                                     "estimator_poles": _poles_json(d.estimator_poles)}
        out["altitude"]["lqg"] = {"K": d.K.tolist(), "regulator_poles": _poles_json(d.regulator_poles),
                                  "closed_loop_poles": _poles_json(d.poles),
                                  "separation_error": match_poles(union, d.poles)}
    return out


def format_sensors_report(rep: dict[str, Any]) -> str:
    """Human-readable text of :func:`sensors_report`."""
    lines = [f"\n== Sensors: {' '.join(rep['sensors']) or '(none)'}"]
    for key in ("altitude", "attitude", "translational"):
        s = rep[key]
        lines.append(f"{key} model, outputs [{' '.join(s['outputs'])}]: observability rank "
                     f"{s['observability_rank']} of {s['n_states']}")
        if s["unobservable_basis"]:
            lines.append("  unobservable directions (rows, over " + " ".join(s["states"]) + "):")
            lines.append(_fmt_matrix(s["unobservable_basis"]))
    alt = rep["altitude"]
    if "kalman" in alt:
        k, g = alt["kalman"], alt["lqg"]
        lines += ["altitude model: steady-state Kalman gain (lqe) L =", _fmt_matrix(k["L"]),
                  f"estimator poles: {_fmt_poles(k['estimator_poles'])}",
                  f"LQG: regulator poles {_fmt_poles(g['regulator_poles'])}",
                  f"LQG closed-loop poles: {_fmt_poles(g['closed_loop_poles'])}",
                  f"separation: closed-loop poles = regulator + estimator poles to {g['separation_error']:.1e}"]
    else:
        lines.append("altitude model: not observable with these sensors, no Kalman gain")
    return "\n".join(lines)
