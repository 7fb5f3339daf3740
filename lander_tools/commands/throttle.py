"""``lander throttle X [--thruster I]``: set the running flight's throttles by hand.

``X`` (0..1) goes to every thruster, or with ``--thruster I`` to thruster ``I`` alone (0-based, as
the scene's ``vehicle.disabled`` counts them) with the others at 0. Published on
``/lander/throttle`` with ``state_sequence`` 0: the simulator holds it (zero-order hold; for good
in a flight without autopilot, ``lander fly SCENE --controller none``; an autopilot's next answer
replaces it) and a paused simulator's ``lander step N`` flies it. The thruster count is the
simulator's scene's (its ``scene`` parameter). Bad input (X outside [0, 1] or not finite, a
thruster the lander does not have) is one line, exit 2; a refusal by the simulator (its
INPUT_REJECTED event, counted in its ``/diagnostics`` as ``rejected.throttle.*``) exit 1; no
flight, exit 3.
"""
import argparse
import math


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from lander_tools.live.verbs import add_wait_argument

    parser.add_argument("throttle", type=float, metavar="X", help="throttle, 0 (off) to 1 (full thrust)")
    parser.add_argument("--thruster", type=int, metavar="I",
                        help="only this thruster (0-based); the others are set to 0 (default: all thrusters)")
    add_wait_argument(parser)


def throttles(value: float, n_thrusters: int, thruster: int | None) -> list[float]:
    """The command: ``value`` on every thruster, or on ``thruster`` alone (the others 0).
    ValueError naming the value or the thruster when they do not fit the lander."""
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ValueError(f"throttle X = {value!r}: must be a number from 0 to 1")
    if thruster is None:
        return [float(value)] * n_thrusters
    if not 0 <= thruster < n_thrusters:
        raise ValueError(f"--thruster {thruster}: the flight's lander has {n_thrusters} thrusters, "
                         f"numbered 0 to {n_thrusters - 1}")
    return [float(value) if i == thruster else 0.0 for i in range(n_thrusters)]


def run(args: argparse.Namespace) -> int:
    from lander_tools.live.link import SIM_NODE, FlightLink, Outcome
    from lander_tools.live.verbs import run_verb

    throttles(args.throttle, max(1, (args.thruster or 0) + 1), args.thruster)  # the value, before any wait

    def act(link: FlightLink) -> Outcome:
        from lander_sim.scenes import load_scene

        scene = link.get_parameters(SIM_NODE, ["scene"]).get("scene")
        if not isinstance(scene, str):
            raise ValueError(f"{SIM_NODE} has no 'scene' parameter: cannot tell how many thrusters it has")
        command = throttles(args.throttle, load_scene(scene).vehicle.n_thrusters, args.thruster)
        out = link.publish_throttles(command, wait=True)
        if out.ok:
            return Outcome(True, f"throttles {', '.join(f'{x:g}' for x in command)} sent on /lander/throttle "
                                 f"({out.message})")
        return out

    return run_verb("throttle", act, wait=args.wait)
