"""``lander design SCENE [--json]``: the control design report for a scene's vehicle.

Prints the altitude (eq 16) and attitude (eq 28) models, controllability rank, uncontrollable
directions, pole-placement and LQR gains and the closed-loop poles, like seed 2's Octave
scripts; ``--json`` prints the same as JSON. ``--write FILE`` also writes the pole-placement gains
as a gains file for ``lander fly SCENE --gains FILE`` (lander_tools.gains). Heavy imports (python-control) happen in :func:`run`.
"""
from __future__ import annotations

import argparse
from pathlib import Path


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
    parser.add_argument("--write", metavar="FILE", type=Path,
                        help="also write the pole-placement gains as a gains file: fly them with "
                             "'lander fly SCENE --gains FILE'")
    parser.add_argument("--controller", default="combined", metavar="NAME",
                        help="with --write: the law the gains are for: combined (default; K_altitude and "
                             "K_attitude), altitude (K), attitude-euler (K)")


def run(args: argparse.Namespace) -> int:
    import json
    import sys

    from lander_autopilot.design.report import design_report, format_report
    from lander_sim.scenes import load_scene

    try:
        if args.write is not None:
            from lander_tools.gains import DESIGN_GAINS, GainsError

            if args.controller not in DESIGN_GAINS:
                raise GainsError(f"--controller {args.controller!r}: a gains file can be written for "
                                 f"{', '.join(DESIGN_GAINS)} (the laws that take the design's K)")
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
    if args.write is not None:
        from lander_tools.gains import check_gains, design_gains, gains_text

        try:
            if args.write.is_dir():
                raise ValueError(f"--write {args.write}: is a folder; give a file name (e.g. gains.yaml)")
            params = design_gains(rep, args.controller)
            check_gains(args.scene, args.controller, params, f"--write {args.write}")
            poles = (f"--altitude-poles {' '.join(f'{p:g}' for p in args.altitude_poles)} "
                     f"--attitude-poles {' '.join(f'{p:g}' for p in args.attitude_poles)}")
            comment = (f"Gains of 'lander design {args.scene} {poles} --fuel {fuel:g}' for controller "
                       f"{args.controller!r}\n(pole placement, K verbatim, designed at {fuel:g} kg of fuel).\n"
                       f"Fly them: lander fly {args.scene} --gains {args.write}")
            args.write.write_text(gains_text(args.controller, params, comment))
        except (ValueError, OSError) as exc:
            print(f"lander design: {exc}", file=sys.stderr)
            return 2
    text = f"scene {scene.name}\n" + format_report(rep)
    if "sensors" in rep:
        from lander_autopilot.design.report import format_sensors_report

        text += "\n" + format_sensors_report(rep["sensors"])
    print(json.dumps(rep, indent=2) if args.json else text)
    if args.write is not None and not args.json:
        print(f"\ngains for controller {args.controller!r} written to {args.write}: "
              f"fly them with 'lander fly {args.scene} --gains {args.write}'")
    return 0
