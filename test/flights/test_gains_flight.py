"""`lander fly --gains`: the gains `lander design --write` wrote fly (the real launcher, sim and
autopilot over ROS), and the summary echoes the gains in force as the autopilot reports them; a
controller flown on a scene whose thrusters cannot control its axes is said at start-up."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from lander_tools import cli


def fly(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", "fly", *argv, "--speed", "0", "--no-progress"],
                          capture_output=True, text=True, timeout=300)


def test_the_designed_gains_fly_and_the_summary_echoes_them(module_ros_domain: int, tmp_path: Path) -> None:
    gains = tmp_path / "gains.yaml"
    # Slower altitude poles than the seed's: K = [p1 p2, -(p1 + p2)] m / T_v (eq 20).
    assert cli.main(["design", "hover-canted", "--altitude-poles", "-0.5", "-0.6", "--write", str(gains)]) == 0
    done = fly("hover-canted", "--gains", str(gains), "--duration", "3")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "[fly] scene 'hover-canted', controller combined," in done.stdout
    line = next(ln for ln in done.stdout.splitlines() if ln.startswith("  controller "))
    # eq 20: K = [p1 p2, -(p1 + p2)] / b with b = T_v / m at the design fuel (the scene's full tank).
    from lander_autopilot.design.altitude import altitude_model
    from lander_sim.scenes import load_scene

    scene = load_scene("hover-canted")
    b = float(altitude_model(scene.vehicle, float(scene.initial_state[13]), 0.0).B[1, 0])
    expected = f"K_altitude [[{0.5 * 0.6 / b:.5g}, {(0.5 + 0.6) / b:.5g}]], K_attitude [["
    assert line.startswith(f"  controller 'combined': gains in force {expected}"), line
    assert "warning" not in done.stdout  # canted thrusters: every axis controllable


def test_a_controller_whose_axes_the_scene_cannot_control_is_said_at_start_up(module_ros_domain: int) -> None:
    done = fly("8", "--controller", "combined", "--duration", "1")
    assert done.returncode == 0, done.stdout + done.stderr
    warnings = [ln for ln in done.stdout.splitlines() if ln.startswith("[fly] warning: ")]
    assert len(warnings) == 1 and "attitude controllability rank 2 of 6" in warnings[0], done.stdout


def test_switch_flies_a_gains_file_while_flying(module_ros_domain: int, tmp_path: Path) -> None:
    import yaml
    from live.liveutil import start_flight, wait_flight_running

    from lander_tools.gains import read_gains
    from lander_tools.live.link import FlightLink

    gains = tmp_path / "gains.yaml"
    assert cli.main(["design", "hover-canted", "--altitude-poles", "-0.5", "-0.6", "--write", str(gains)]) == 0
    flight = start_flight(tmp_path, scene="hover-canted", speed=1.0, duration=600.0)
    try:
        wait_flight_running(flight)
        done = subprocess.run([sys.executable, "-m", "lander_tools.cli", "switch", "--gains", str(gains)],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr + flight.output()
        assert done.stdout.startswith("lander switch: switched 'combined-quaternion' -> 'combined'"), done.stdout
        with FlightLink("test_switch_gains") as link:
            now = link.get_parameters("/autopilot", ["controller", "controller_params"])
        assert now["controller"] == "combined"
        assert yaml.safe_load(now["controller_params"]) == read_gains(gains)[1]  # the file's gains, every bit
        assert flight.returncode is None, flight.output()
    finally:
        flight.close()
