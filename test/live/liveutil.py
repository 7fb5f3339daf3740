"""Helpers for the live tests: a flight and a bridge as real child processes; the Foxglove
client is :class:`lander_tools.live.wsclient.FoxgloveClient`."""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

import rosutil
from lander_ros.stamps import stamp_to_seconds
from lander_tools.live.wsclient import FoxgloveClient as FoxgloveTestClient  # noqa: F401 - for the tests
from lander_tools.live.wsclient import wait_until


def start_flight(tmp: Path, scene: str = "hover-canted", speed: float = 5.0, duration: float = 600.0,
                 dt: float | None = None, extra: list[str] | None = None) -> rosutil.ChildProcess:
    """``lander fly SCENE`` as a child process (the real launcher: sim + autopilot, lockstep)."""
    args = ["-m", "lander_tools.cli", "fly", scene, "--speed", str(speed), "--duration", str(duration),
            "--no-progress"]
    if dt is not None:
        params = tmp / "params.yaml"
        params.write_text(f"lander_sim:\n  ros__parameters:\n    dt: {dt}\n")
        args += ["--params", str(params)]
    return rosutil.ChildProcess(args + list(extra or []), name="fly")


def start_bridge(extra: list[str] | None = None) -> tuple[rosutil.ChildProcess, int, int]:
    """``lander live --port 0`` as a child process; returns it and its (ws, page) ports once it
    has printed them."""
    child = rosutil.ChildProcess(["-m", "lander_tools.cli", "live", "--port", "0", *(extra or [])], name="live")
    found = wait_until(lambda: re.search(r"ws://127\.0\.0\.1:(\d+)\s+student page http://127\.0\.0\.1:(\d+)/",
                                         child.output()) or (child.returncode is not None and child.output() + " "),
                       60.0, "the bridge's URLs")
    if isinstance(found, str):
        raise RuntimeError(f"the bridge exited: {found}")
    return child, int(found.group(1)), int(found.group(2))


def wait_flight_running(fly: rosutil.ChildProcess, timeout: float = 90.0, after_t: float = 0.5) -> None:
    """Wait until the flight's simulator and autopilot are up and a state past ``after_t`` s of sim
    time has been published (the launcher has reset and resumed the flight); RuntimeError with
    the flight's output if ``fly`` exits first."""
    from lander_tools.live.link import SIM_NODE, FlightLink

    def alive() -> None:
        if fly.returncode is not None:
            lines = [ln for ln in fly.output().splitlines() if "state lost" not in ln]  # the autopilot's 1 Hz noise
            raise RuntimeError(f"the flight exited ({fly.returncode}):\n" + "\n".join(lines[-40:]))

    with FlightLink("test_live_wait") as link:
        for node in (SIM_NODE, "/autopilot"):
            wait_until(lambda n=node: alive() or n in link.node_names(), timeout, f"{node} in the graph")
        times: list[float] = []
        wait_until(lambda: alive() or "/lander/state" in dict(link.topics()), timeout, "the state topic")
        link.subscribe("/lander/state", "lander_interfaces/msg/LanderState",
                       lambda m: times.append(stamp_to_seconds(m.header.stamp)), depth=10)
        wait_until(lambda: alive() or (times and times[-1] > after_t), timeout, f"a state after t = {after_t} s")


# --- the student page in a real browser ----------------------------------------------------------

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 # WebGL (the 3-D view) on the CPU: SwiftShader, Chromium's own software renderer
                 "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def chromium_path() -> str:
    """Debian's chromium (installed by `lander_tools/setup_env.py` on CI's machine). Absent: a loud
    skip on a developer's machine, a failure in CI (CI=true), where the set-up must have put it."""
    import os
    import shutil

    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        reason = ("Debian's chromium is not installed: the student page's browser test CANNOT RUN here "
                  "(install it: apt-get install chromium, or run ./dev as root once)")
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    return path


def launch_chromium(pw: Any) -> Any:
    """Headless Debian Chromium through Playwright (never a downloaded browser)."""
    return pw.chromium.launch(executable_path=chromium_path(), args=CHROMIUM_ARGS, headless=True)


def console_errors(page: Any) -> list[str]:
    """The page's uncaught exceptions and console errors (a failed load, a 404, ...), as they come."""
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    return errors
