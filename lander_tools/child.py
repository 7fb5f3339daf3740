"""Run a module as a child process that dies with its parent.

``python -m lander_tools.child PARENT_PID MODULE [ARGS...]`` runs ``python -m MODULE ARGS...``
in this process, after asking the kernel to send it SIGTERM when its parent dies.

Why: the launcher starts the nodes in their own session, so that a terminal's Ctrl-C reaches only
the launcher, which then stops them in order. A launcher killed without its clean-up (SIGKILL from
a time limit, the OOM killer) would leave them running: a lockstep sim and its autopilot go on
flying at full speed on the same ROS domain, eat the CPU and answer the next flight's states.
SIGTERM is the nodes' clean exit (as SIGINT is).

``PR_SET_PDEATHSIG`` is Linux-only; elsewhere the module runs without the guard.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import runpy
import signal
import sys

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def die_with_parent(parent_pid: int) -> bool:
    """Ask for SIGTERM when the parent dies; False if the parent is already gone (or not ours)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    # The parent may have died between fork and prctl: then we were re-parented already.
    return os.getppid() == parent_pid


def command(module: str, args: list[str]) -> list[str]:
    """The command line that runs ``python -m module args`` as a child of this process."""
    return [sys.executable, "-m", "lander_tools.child", str(os.getpid()), module, *args]


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print("usage: python -m lander_tools.child PARENT_PID MODULE [ARGS...]", file=sys.stderr)
        return 2
    if not die_with_parent(int(argv[0])):
        print(f"lander_tools.child: parent {argv[0]} is gone; not starting {argv[1]}", file=sys.stderr)
        return 1
    sys.argv = [argv[1], *argv[2:]]
    runpy.run_module(argv[1], run_name="__main__", alter_sys=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
