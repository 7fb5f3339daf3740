"""Run a module as a child process that dies with its parent.

``python -m lander_tools.child PARENT_PID MODULE [ARGS...]`` runs ``python -m MODULE ARGS...``
in this process, after asking the kernel to send it SIGTERM when its parent dies.

Why: the launcher starts the nodes in their own session, so that a terminal's Ctrl-C reaches only
the launcher, which then stops them in order. A launcher killed without its clean-up (SIGKILL from
a time limit, the OOM killer) would leave them running: a lockstep sim and its autopilot go on
flying at full speed on the same ROS domain, eat the CPU and answer the next flight's states.
SIGTERM is the nodes' clean exit (as SIGINT is).

That clean exit is bounded: once the parent is gone, a kernel timer (``SIGALRM`` at its default
action, which needs no Python) ends the process :data:`PARENT_GONE_GRACE` s later whatever it is
doing. Seen in CI: a sim whose launcher was SIGKILLed stuck for good in ``destroy_node`` (Fast DDS
deadlocks destroying a participant while it removes a dead remote one; the call holds the GIL, so
no Python-level wait can end it). And once the module's ``main`` has returned (node destroyed,
context shut down) the process ends at once: the interpreter's teardown of numpy/scipy/control
took another ~1.5 s (measured), the time a teardown check waits for.

``PR_SET_PDEATHSIG`` and ``pidfd_open`` are Linux-only; elsewhere the module runs without the guard.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import runpy
import select
import signal
import sys
import threading

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
#: Wall seconds a node gets for its clean exit (flush <= 1 s, destroy) after its parent died.
PARENT_GONE_GRACE = 4.0


def die_with_parent(parent_pid: int) -> bool:
    """Ask for SIGTERM when the parent dies; False if the parent is already gone (or not ours)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    # The parent may have died between fork and prctl: then we were re-parented already.
    return os.getppid() == parent_pid


def end_after_parent(parent_pid: int, grace: float = PARENT_GONE_GRACE) -> bool:
    """Watch the parent (a pidfd, no polling); when it dies, arm a ``grace`` s SIGALRM that ends
    this process even if it is stuck in C. False where pidfds are missing (no guard)."""
    try:
        fd = os.pidfd_open(parent_pid)
    except (AttributeError, OSError):
        return False

    def watch() -> None:
        poller = select.poll()
        poller.register(fd, select.POLLIN)
        poller.poll()  # readable once the parent has exited
        signal.setitimer(signal.ITIMER_REAL, grace)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
    return True


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
    end_after_parent(int(argv[0]))
    sys.argv = [argv[1], *argv[2:]]
    try:
        runpy.run_module(argv[1], run_name="__main__", alter_sys=True)
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            return exc.code or 0
        print(exc.code, file=sys.stderr)  # sys.exit("message"), as the interpreter would show it
        return 1
    return 0


def exit_now(code: int) -> None:
    """End the process with ``code`` after flushing stdio, skipping the interpreter's teardown."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # the parent (reader of our pipe) is gone
            pass
    os._exit(code)


if __name__ == "__main__":
    exit_now(main(sys.argv[1:]))
