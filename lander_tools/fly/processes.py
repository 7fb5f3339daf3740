"""The node processes of a flight: their command lines and parameter files, a node in its own
process with its output forwarded under a prefix, and the stop in order (autopilot first)."""
from __future__ import annotations

import signal
import subprocess
import threading
from pathlib import Path
from typing import Any, TextIO

import yaml

from lander_autopilot.ros.config import dump_controller_params, parse_controller_params, scene_autopilot
from lander_sim.scenes import load_scene
from lander_tools import child
from lander_tools.fly.checks import read_params_file
from lander_tools.fly.navigation import estimate_params
from lander_tools.fly.plan import AUTOPILOT_NODE, ESTIMATOR_NODE, SIM_NODE, FlightPlan, pilot_mode

#: Wall seconds a node gets to stop after SIGINT, then again after SIGTERM.
STOP_GRACE = 5.0


class NodeProcess:
    """A node in its own process, with its output forwarded line by line under a prefix."""

    def __init__(self, name: str, argv: list[str], out: TextIO, env: dict[str, str] | None = None) -> None:
        self.name = name
        self.argv = argv
        # Own session: a terminal's Ctrl-C reaches only the launcher, which then stops the
        # nodes in order (nodes first, bag last) instead of all at once.
        self.proc = subprocess.Popen(
            argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,
            text=True,
            bufsize=1,
        )
        self.lines: list[str] = []  # last lines, for error messages
        self._thread = threading.Thread(target=self._forward, args=(out,), daemon=True)
        self._thread.start()

    def _forward(self, out: TextIO) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines = (self.lines + [line.rstrip()])[-20:]
            out.write(f"[{self.name}] {line}")
            out.flush()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, grace: float = STOP_GRACE, interrupted: bool = False) -> int | None:
        """SIGINT (the nodes' clean exit), then SIGTERM, then SIGKILL; returns the exit code.

        ``interrupted``: SIGINT was already sent; a second one would break the node's clean-up.
        """
        for sig in (None if interrupted else signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if self.proc.poll() is not None:
                break
            try:
                if sig is not None:
                    self.proc.send_signal(sig)
                self.proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                continue
            except ProcessLookupError:
                break
        self._thread.join(timeout=2.0)
        return self.proc.returncode


def stop_all(procs: dict[str, NodeProcess]) -> None:
    """Signal every node to stop (autopilot first), then wait for each (see NodeProcess.stop)."""
    order = sorted(procs.values(), key=lambda p: (p.name != "autopilot", p.name != "estimator"))
    interrupted: set[str] = set()
    for p in order:
        if p.alive():
            try:
                p.proc.send_signal(signal.SIGINT)
                interrupted.add(p.name)
            except ProcessLookupError:
                pass
    for p in order:
        p.stop(interrupted=p.name in interrupted)


def _params_yaml(node: str, params: dict[str, Any], folder: Path) -> Path:
    path = folder / f"{node}.params.yaml"
    path.write_text(yaml.safe_dump({node: {"ros__parameters": params}}, sort_keys=True))
    return path


def node_commands(plan: FlightPlan, controller: str | None, folder: Path, flight_id: str = "") -> dict[str, list[str]]:
    """The command lines of the node processes (``sim``, ``autopilot`` or ``composed``).

    Each node gets one parameters file: its section of the user's ``--params`` file
    (:func:`read_params_file`), then the flight's settings, which win. ``flight_id``: the sim then
    takes throttles only from the flight's own nodes (lander_ros.strangers)."""
    user = read_params_file(plan.params_file) if plan.params_file is not None else {SIM_NODE: {}, AUTOPILOT_NODE: {}}
    sim_params = dict(user[SIM_NODE])
    sim_params.update({
        "scene": plan.scene, "speed": float(plan.speed), "start_paused": True,
        # The sim stops by itself at the end instant, and its diagnostics are the flight's only.
        "end_time": float(plan.duration) if plan.duration is not None else -1.0,
        "end_on": ",".join(plan.end_on), "idle_diagnostics": False,
    })
    if flight_id:
        sim_params["flight_id"] = flight_id
        sim_params["flight_nodes"] = "/autopilot /lander_fly" if controller is not None else "/lander_fly"
    if controller is not None:
        sim_params["lockstep"] = plan.lockstep is not False
    else:
        sim_params["lockstep"] = pilot_mode(plan, controller)
        # The sim alone holds the last command (the user's or the timeline's) for good.
        sim_params["command_timeout"] = 0.0
    sim_params.update(plan.sim_params)
    sim_file = _params_yaml(SIM_NODE, sim_params, folder)
    cmds: dict[str, list[str]] = {}
    ap_args: list[str] = []
    est_params = _estimator_params(plan, sim_params, flight_id) if plan.estimate else {}
    if controller is not None:
        ap_params: dict[str, Any] = dict(user[AUTOPILOT_NODE])
        ap_params.update({"scene": plan.scene, "controller": controller, "use_sim_time": True})
        if flight_id:
            ap_params["flight_id"] = flight_id
        if plan.controller_params:
            ap_params["controller_params"] = yaml.safe_dump(
                dict(plan.controller_params), default_flow_style=True, sort_keys=True
            ).strip()
        if plan.estimate:
            ap_params["state_source"] = "estimate"
        ap_params.update(plan.autopilot_params)
        if plan.estimate:
            _tell_navigation_error(ap_params, plan.scene, est_params)
        ap_args = ["--params-file", str(_params_yaml(AUTOPILOT_NODE, ap_params, folder))]
    if plan.compose and controller is not None:
        cmds["composed"] = child.command("lander_tools.fly.composed", ["--ros-args", "--params-file", str(sim_file),
                                                                      *ap_args])
    else:
        cmds["sim"] = child.command("lander_sim.node", ["--ros-args", "--params-file", str(sim_file)])
        if controller is not None:
            cmds["autopilot"] = child.command("lander_autopilot.node", ["--ros-args", *ap_args])
    if plan.estimate:
        cmds["estimator"] = child.command("lander_autopilot.estimator_node",
                                          ["--ros-args", "--params-file",
                                           str(_params_yaml(ESTIMATOR_NODE, est_params, folder))])
    return cmds


def _estimator_params(plan: FlightPlan, sim_params: dict[str, Any], flight_id: str) -> dict[str, Any]:
    """The estimator node's parameters: its scene, and its initial error drawn with the sim's seed
    (-1: the scene's sensors.seed)."""
    est_params: dict[str, Any] = {"scene": plan.scene, "seed": int(sim_params.get("seed", -1))}
    if flight_id:
        est_params["flight_id"] = flight_id
    return est_params


def _tell_navigation_error(ap_params: dict[str, Any], scene: str, est_params: dict[str, Any]) -> None:
    """On the estimate, a law that plans from its first state is given the estimator's initial sigmas
    (lander_tools.fly.navigation) in ``ap_params["controller_params"]``, on top of the parameters the
    autopilot would fly otherwise: those given, else the scene's autopilot parameters (its default)."""
    if "controller_params" in ap_params:
        base = parse_controller_params(ap_params["controller_params"])
    else:
        base = dict(scene_autopilot(load_scene(scene)).parameters)
    completed = estimate_params(str(ap_params["controller"]), base, est_params)
    if completed is not None:
        ap_params["controller_params"] = dump_controller_params(completed)
