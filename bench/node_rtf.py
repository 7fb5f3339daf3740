"""Benchmark: real-time factor achieved by the simulation node (not a test).

The real node runs as a subprocess at speed 0 (as fast as possible), 1 kHz physics and
50 Hz publishing, flying the full lander scene; this process measures sim seconds per wall
second from the node's /clock, once with nobody subscribed to the state topics and once
with a subscriber on /lander/state, /lander/odom and /lander/pose. Goal: at least 50x.

    ./dev exec python bench/node_rtf.py [--json F] [--quick] [--scene hover-canted]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GOAL = 50.0


def _measure(scene: str, dt: float, seconds: float, subscribe: bool) -> dict:
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    from lander_interfaces.msg import LanderState

    args = [sys.executable, "-m", "lander_sim.node", "--ros-args", "-p", f"scene:={scene}", "-p", f"dt:={dt}",
            "-p", "publish_rate:=50.0", "-p", "speed:=0.0", "-p", "command_timeout:=0.0"]
    proc = subprocess.Popen(args, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=os.environ.copy())
    node = rclpy.create_node("node_rtf_bench")
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    clocks: list[tuple[float, int]] = []
    received = [0]
    node.create_subscription(Clock, "/clock", lambda m: clocks.append((time.monotonic(), m.clock.sec * 10**9 + m.clock.nanosec)), 100)
    if subscribe:
        count = lambda _m: received.__setitem__(0, received[0] + 1)  # noqa: E731
        for typ, topic in ((LanderState, "/lander/state"), (Odometry, "/lander/odom"), (PoseStamped, "/lander/pose")):
            node.create_subscription(typ, topic, count, 100)
    try:
        deadline = time.monotonic() + 60.0
        while len(clocks) < 10:  # the node is up and our subscriptions matched
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError("the sim node did not start publishing /clock")
            ex.spin_once(timeout_sec=0.05)
        w0, t0 = clocks[-1]
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        w1, t1 = clocks[-1]
    finally:
        proc.send_signal(2)
        proc.wait(timeout=10)
        ex.remove_node(node)
        node.destroy_node()
    rtf = (t1 - t0) * 1e-9 / (w1 - w0)
    return {"scene": scene, "dt": dt, "publish_rate": 50.0, "subscriber": subscribe, "wall_s": w1 - w0,
            "sim_s": (t1 - t0) * 1e-9, "rtf": rtf, "messages_received": received[0], "goal_met": rtf >= GOAL}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, help="also write the results to this JSON file")
    ap.add_argument("--quick", action="store_true", help="2 s per case instead of 8 s")
    ap.add_argument("--scene", default="hover-canted",
                    help="scene to fly (default: hover-canted, scenario 7 flying free: the full lander without the stabiliser aid)")
    a = ap.parse_args(argv)
    import rclpy

    # Isolated from whatever else runs on this machine: own domain, loopback only.
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rclpy.init()
    try:
        rows = [_measure(a.scene, 0.001, 2.0 if a.quick else 8.0, sub) for sub in (False, True)]
    finally:
        rclpy.try_shutdown()
    print(f"sim node real-time factor: scene {a.scene}, 1 kHz physics, 50 Hz publishing, speed 0 (goal >= {GOAL:g}x)")
    print(f"{'subscriber':>10} {'wall s':>8} {'sim s':>8} {'RTF':>8} {'msgs rx':>8}  goal")
    for r in rows:
        print(f"{'yes' if r['subscriber'] else 'no':>10} {r['wall_s']:8.2f} {r['sim_s']:8.2f} {r['rtf']:8.1f} "
              f"{r['messages_received']:8d}  {'met' if r['goal_met'] else 'NOT met'}")
    if a.json:
        a.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
