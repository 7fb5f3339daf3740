"""The CLI verbs with no flight running: each exits 3 with one line saying so (real `lander`
processes, all at once). With a flight: test_live_flight.py."""
from __future__ import annotations

import subprocess
import sys

VERBS_NO_FLIGHT = [["demand", "510"], ["wind", "1", "0", "0"], ["switch", "lqr"], ["pause"], ["resume"],
                   ["step", "3"], ["reset"], ["topics"], ["echo", "/lander/state", "--once"],
                 ["throttle", "0.2"], ["stabiliser", "on"], ["parachute"]]


def test_each_verb_says_in_one_line_that_no_flight_is_running(module_ros_domain: int) -> None:
    procs = [subprocess.Popen([sys.executable, "-m", "lander_tools.cli", *argv], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for argv in VERBS_NO_FLIGHT]
    for argv, p in zip(VERBS_NO_FLIGHT, procs):
        out, err = p.communicate(timeout=120)
        lines = err.strip().splitlines()
        assert p.returncode == 3, (argv, out, err)
        assert len(lines) == 1 and lines[0].startswith(f"lander {argv[0]}: no flight running: /lander_sim not seen"), err
        assert "within 3 s" in lines[0] and out == ""


