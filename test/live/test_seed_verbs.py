"""The seed tasks' verbs against a real flight (`lander fly hover --controller none`, the real
launcher; each verb a real `lander` process): `lander throttle` sets every thruster or one and the
simulator flies it, `lander stabiliser on|off` and `lander parachute` act and the state says so; bad
input is one line naming what was wrong, exit 2, and a deployment the scene cannot make is the
simulator's refusal, exit 1. Without a flight: test_verbs_no_flight.py."""
from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

from lander_tools.live.link import FlightLink
from lander_tools.live.wsclient import wait_until

from .liveutil import start_flight

TIMEOUT = 60.0


def lander(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", *argv], capture_output=True, text=True,
                          timeout=120)


def wait_flight_started(fly, link: FlightLink, on_state) -> None:
    """Wait until a flight without autopilot publishes states past t = 0.5 s (the launcher has reset
    and resumed it), handing each to ``on_state``; RuntimeError with its output if it exits first."""
    from lander_ros.stamps import stamp_to_seconds

    def alive() -> None:
        if fly.returncode is not None:
            raise RuntimeError(f"the flight exited ({fly.returncode}):\n{fly.output()}")

    times: list[float] = []
    wait_until(lambda: alive() or "/lander/state" in dict(link.topics()), TIMEOUT, "the state topic")

    def seen(msg) -> None:
        times.append(stamp_to_seconds(msg.header.stamp))
        on_state(msg)

    link.subscribe("/lander/state", "lander_interfaces/msg/LanderState", seen, depth=10)
    wait_until(lambda: alive() or (times and times[-1] > 0.5), TIMEOUT, "a state after t = 0.5 s")


def test_throttle_stabiliser_and_parachute_act_on_the_flight(module_ros_domain: int, tmp_path: Path) -> None:
    # A quarter of real time: without thrust the lander falls from 550 m, and 0.7 must come within
    # ~9 s of sim time (1.86 t^2 falling + (3.71 t)^2 / (2 x 1.52) braking < 550 m), which the
    # first verb's start-up (a new process, discovery) could outlast on a loaded machine at speed 1.
    fly = start_flight(tmp_path, scene="hover", speed=0.25, duration=600.0, extra=["--controller", "none"])
    try:
        latest: list = []
        lock = threading.Lock()

        def on_state(msg) -> None:
            with lock:
                latest[:] = [msg]

        def state():
            with lock:
                return latest[0] if latest else None

        with FlightLink("test_seed_verbs") as link:
            wait_flight_started(fly, link, on_state)
            # The lander falls from 550 m without thrust: 0.7 (above the hover throttle, ~0.5 for this
            # lander) brakes it at ~1.5 m/s^2 and holds it up for the rest of the test.
            done = lander("throttle", "0.7")
            assert done.returncode == 0, done.stderr + fly.output()
            assert done.stdout.startswith("lander throttle: throttles 0.7, 0.7, 0.7, 0.7 sent"), done.stdout
            wait_until(lambda: list(state().throttles) == [0.7] * 4, TIMEOUT, "all four throttles at 0.7")

            done = lander("throttle", "0.3", "--thruster", "2")
            assert done.returncode == 0, done.stderr + fly.output()
            wait_until(lambda: list(state().throttles) == [0.0, 0.0, 0.3, 0.0], TIMEOUT, "thruster 2 alone at 0.3")
            assert lander("throttle", "0.7").returncode == 0

            assert state().stabiliser_on  # the scene's: on
            done = lander("stabiliser", "off")
            assert done.returncode == 0 and done.stdout.strip() == "lander stabiliser: stabiliser off", done
            wait_until(lambda: not state().stabiliser_on, TIMEOUT, "the stabiliser off")
            assert lander("stabiliser", "on").returncode == 0
            wait_until(lambda: state().stabiliser_on, TIMEOUT, "the stabiliser on again")

            assert not state().parachute_deployed
            done = lander("parachute")
            assert done.returncode == 0, done.stderr
            wait_until(lambda: state().parachute_deployed, TIMEOUT, "the parachute out")

        # Bad input: one line naming it, exit 2, nothing sent.
        for argv, words in ((["throttle", "1.5"], "throttle X = 1.5: must be a number from 0 to 1"),
                            (["throttle", "nan"], "must be a number from 0 to 1"),
                            (["throttle", "0.2", "--thruster", "4"], "--thruster 4: the flight's lander has 4 thrusters"),
                            (["stabiliser", "maybe"], "invalid choice: 'maybe'")):
            done = lander(*argv)
            lines = done.stderr.strip().splitlines()
            assert done.returncode == 2 and len(lines) == 1 and words in lines[0], (argv, done.stderr)
        assert fly.returncode is None, fly.output()  # still flying
    finally:
        fly.close()


def test_a_parachute_the_scene_does_not_have_is_refused_by_the_simulator(module_ros_domain: int,
                                                                         tmp_path: Path) -> None:
    fly = start_flight(tmp_path, scene="free-spin", speed=1.0, duration=600.0, extra=["--controller", "none"])
    try:
        with FlightLink("test_seed_verbs") as link:
            wait_flight_started(fly, link, lambda _msg: None)
        done = lander("parachute")
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1, done
        assert lines[0].startswith("lander parachute: refused by the flight: ") and "has no parachute" in lines[0]
    finally:
        fly.close()
