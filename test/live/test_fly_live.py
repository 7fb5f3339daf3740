"""`lander fly SCENE --live`: the bridge starts with the flight, is counted by the launcher's
start-up handshake (so the flight starts only once the autopilot and the bridge are matched), serves
a client during the flight and leaves with it."""
from __future__ import annotations

import re
import socket
import subprocess
import sys

from lander_tools.live.wsclient import FoxgloveClient


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_fly_live_serves_the_flight_and_ends_with_it(module_ros_domain: int) -> None:
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "lander_tools.cli", "fly", "hover-canted", "--speed", "2",
                             "--duration", "6", "--no-progress", "--live", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    client = None
    try:
        while client is None and proc.poll() is None:
            try:
                client = FoxgloveClient(port, timeout=2.0)
            except RuntimeError:
                continue  # the bridge is not serving yet: try again (each try waits up to 2 s)
        assert client is not None, "the flight ended before its bridge served"
        client.wait_channels(["/live/state"])
        client.subscribe(["/live/state"])
        out, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
        if client is not None:
            client.close()
    assert proc.returncode == 0, out
    assert re.search(rf"\[live\] live: Foxglove server ws://127\.0\.0\.1:{port}\s+student page "
                     rf"http://127\.0\.0\.1:{port + 1}/", out), out
    states = client.json_messages("/live/state")
    assert states and states[-1]["t"] > 1.0, out  # the client saw the flight fly
    assert states[-1]["controller"] == "combined-quaternion"
