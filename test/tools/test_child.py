"""lander_tools.child: a node child ends with its launcher, even one that ignores the launcher's death
(a node stuck in its ROS teardown: the CI flake where a sim outlived a SIGKILLed `lander fly`)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import psutil

from lander_tools.child import PARENT_GONE_GRACE

REPO = Path(__file__).resolve().parents[2]
STUCK_NODE = """
import signal, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)  # deaf to PR_SET_PDEATHSIG's SIGTERM, as a stuck node is
print("ready", flush=True)
time.sleep(3600)
"""
LAUNCHER = """
import subprocess, sys
from lander_tools import child
p = subprocess.Popen(child.command("stuck_node", []), stdout=sys.stdout)
print(p.pid, flush=True)
p.wait()
"""


def test_a_child_deaf_to_sigterm_still_ends_within_the_grace_after_its_parent_is_killed(tmp_path: Path) -> None:
    (tmp_path / "stuck_node.py").write_text(STUCK_NODE)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(REPO)]))
    launcher = subprocess.Popen([sys.executable, "-c", LAUNCHER], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert launcher.stdout is not None
        node = psutil.Process(int(launcher.stdout.readline()))
        assert launcher.stdout.readline().strip() == "ready"  # the node runs (and its parent watch)
        launcher.kill()
        launcher.wait()
        # The grace, plus room for a loaded 2-core machine to deliver the timer.
        _, alive = psutil.wait_procs([node], timeout=PARENT_GONE_GRACE + 10.0)
        assert not alive, f"the child outlived its parent by {PARENT_GONE_GRACE + 10.0} s"
    finally:
        launcher.kill()
        launcher.wait()
