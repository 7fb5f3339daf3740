"""``lander fly SCENE``: launch simulator + autopilot on this machine, fly, optionally record.

``SCENE`` may also be a scripted flight (``flights/*.yaml``, see docs/flying.md), which
brings its own controller, timeline and end condition. Scene, controller and flight names and
the ``--params`` file are checked before anything starts (one error line, the closest name
offered); so are ``--gains FILE`` (a gains file of ``lander design --write``) and ``--set NAME=VALUE``,
built for the scene's vehicle as the autopilot will build them (lander_tools.gains). Exit status: 0 landed or time limit, 1 crashed, 2 error (also: another flight runs in the
domain), 3 the bag misses messages or holds another flight's, 130 interrupted (see :mod:`lander_tools.fly`).
Heavy imports (rclpy) happen in :func:`run`, so ``lander fly --help`` stays fast.
"""

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE",
                        help="scenario name or alias (see 'lander scenes'), a scene YAML file, or a scripted flight YAML")
    parser.add_argument("--controller", metavar="NAME",
                        help="autopilot controller plug-in (default: the scene's; 'none' flies the sim alone)")
    parser.add_argument("--record", metavar="BAG", type=Path, help="record the flight to this rosbag2 folder")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="bag storage (default mcap)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="topics to record (default: all the flight's)")
    parser.add_argument("--duration", metavar="S", type=float, help="stop after this much simulated time, s")
    parser.add_argument("--speed", metavar="X", type=float, default=None,
                        help="simulated seconds per wall-clock second (default 1.0; 0 = as fast as possible)")
    parser.add_argument("--params", metavar="FILE", type=Path,
                        help="ROS parameters YAML for the nodes: sections lander_sim (the simulator), autopilot "
                             "(or lander_autopilot) and /** (both), each holding ros__parameters; an unknown "
                             "section or key is an error")
    parser.add_argument("--gains", metavar="FILE", type=Path,
                        help="fly the controller and gains of this file (written by 'lander design SCENE --write "
                             "FILE'); checked against the scene's vehicle before anything starts")
    parser.add_argument("--set", metavar="NAME=VALUE", action="append", default=[], dest="sets",
                        help="one controller parameter (e.g. --set kp=0.2, --set 'altitude_poles=[-0.5, -0.6]'); "
                             "repeat for more; on top of --gains or the scene's parameters")
    parser.add_argument("--estimate", action="store_true",
                        help="start the estimator node beside the sim (the scene needs sensors with an IMU); the "
                             "autopilot flies on its estimate, and the bag holds /lander/estimate/* (docs/estimation.md)")
    parser.add_argument("--compose", action="store_true", help="run sim and autopilot in one process (faster)")
    parser.add_argument("--lockstep", action=argparse.BooleanOptionalAction, default=None,
                        help="sim waits for the autopilot's answer to every state (default: on with an autopilot)")
    parser.add_argument("--no-progress", action="store_true", help="no progress line even on a terminal")
    parser.add_argument("--live", action="store_true",
                        help="serve the flight live: Foxglove server and student page, URLs printed (docs/live.md)")
    parser.add_argument("--port", type=int, default=8765, metavar="P",
                        help="with --live: Foxglove WebSocket port (default 8765; student page on P + 1)")
    parser.add_argument("--domain", type=int, metavar="ID",
                        help="ROS domain of the flight (default: ROS_DOMAIN_ID if set, else one no other flight on "
                             "this machine uses; printed in the first line, and the lander verbs find it)")
    parser.add_argument("--network", action="store_true",
                        help="discover over the network (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET); default: this machine "
                             "only (LOCALHOST) unless ROS_AUTOMATIC_DISCOVERY_RANGE is set (docs/flying.md)")


def run(args: argparse.Namespace) -> int:
    from lander_tools.fly.checks import check_plan
    from lander_tools.fly.phases import fly
    from lander_tools.fly.plan import EXIT_ERROR, FlightPlan, LaunchError
    from lander_tools.fly.summary import summary
    from lander_tools.progress import Progress
    from lander_tools.scripted import (
        ScriptError,
        check_flight_path,
        is_script,
        load_script,
    )

    try:
        check_flight_path(args.scene)
        if is_script(args.scene):
            plan = load_script(args.scene).plan(record=args.record, storage=args.storage)
            if args.controller is not None:
                plan.controller = args.controller
            if args.duration is not None:
                plan.duration = args.duration
            if args.speed is not None:
                plan.speed = args.speed
            plan.params_file = args.params or plan.params_file
        else:
            plan = FlightPlan(
                scene=args.scene, controller=args.controller, duration=args.duration,
                speed=1.0 if args.speed is None else args.speed, lockstep=args.lockstep,
                params_file=args.params, record=args.record, storage=args.storage,
            )
        if args.gains is not None or args.sets:
            from lander_tools.gains import apply_gains

            apply_gains(plan, args.gains, args.sets, explicit_controller=args.controller)
        if args.topics:
            plan.topics = tuple(args.topics)
        plan.compose = plan.compose or args.compose
        plan.estimate = plan.estimate or args.estimate
        if args.lockstep is not None:
            plan.lockstep = args.lockstep
        if args.live:
            plan.live = args.port
        if args.domain is not None:
            from lander_tools.fly.domain import parse_domain

            plan.domain = parse_domain(str(args.domain), "--domain")
        plan.network = plan.network or args.network
        plan.__post_init__()
        check_plan(plan)  # every name and file, before anything starts
    except (LaunchError, ScriptError, ValueError) as exc:
        print(f"lander fly: {exc}", file=sys.stderr)
        return EXIT_ERROR
    progress = Progress(enabled=False if args.no_progress else None, total=plan.duration)
    result = fly(plan, progress=progress)
    print(summary(result))
    return result.exit_code
