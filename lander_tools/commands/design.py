"""``lander design SCENE [--json]``: the control design report for a scene's vehicle.

Prints the altitude (eq 16) and attitude (eq 28) models, controllability rank, uncontrollable
directions, pole-placement and LQR gains and the closed-loop poles, like seed 2's Octave
scripts; ``--json`` prints the same as JSON. Heavy imports (python-control) happen in :func:`run`.
"""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="scene name, alias or YAML path")
    parser.add_argument("--json", action="store_true", help="machine-readable JSON instead of text")
    parser.add_argument("--altitude", type=float, default=500.0, help="hover altitude to linearise about [m]")
    parser.add_argument("--fuel", type=float, default=None, help="fuel mass [kg] (default: the scene's)")
    parser.add_argument(
        "--altitude-poles", type=float, nargs=2, default=(-0.9, -1.1), metavar="P", help="altitude poles (2)"
    )
    parser.add_argument(
        "--attitude-poles", type=float, nargs=6, default=(-1.0,) * 6, metavar="P", help="attitude poles (6)"
    )
    parser.add_argument("--sensors", nargs="*", default=None, metavar="SENSOR",
                        help="add observability, Kalman gain and LQG for these sensors (altimeter doppler star_tracker "
                             "gyro accelerometer)")


def run(args: argparse.Namespace) -> int:
    import json
    import sys

    from lander_autopilot.design.report import design_report, format_report
    from lander_sim.scenes import load_scene

    try:
        scene = load_scene(args.scene)
        fuel = float(scene.initial_state[13]) if args.fuel is None else args.fuel
        rep = design_report(
            scene.vehicle, fuel, args.altitude, tuple(args.altitude_poles), tuple(args.attitude_poles)
        )
        if args.sensors is not None:
            from lander_autopilot.design.report import sensors_report

            rep["sensors"] = sensors_report(scene.vehicle, fuel, tuple(args.sensors), args.altitude)
    except ValueError as exc:
        print(f"lander design: {exc}", file=sys.stderr)
        return 2
    rep = {"scene": scene.name, **rep}
    text = f"scene {scene.name}\n" + format_report(rep)
    if "sensors" in rep:
        from lander_autopilot.design.report import format_sensors_report

        text += "\n" + format_sensors_report(rep["sensors"])
    print(json.dumps(rep, indent=2) if args.json else text)
    return 0
