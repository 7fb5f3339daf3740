"""Debian packages the test suite needs beyond the venv: Chromium for the student page's browser
test (test/live/test_live_flight.py drives Debian's ``chromium`` with Playwright; no browser is
ever downloaded).

Standard library only: ``lander_tools/setup_env.py`` runs it with the system ``python3`` before
the venv exists. Idempotent and quiet when everything is there (one ``shutil.which`` per
package); installs with ``apt-get`` only when it runs as root and ``apt-get`` exists (CI's fresh
Debian 12), logging to ``.venv/.build/log/apt.log``; otherwise, or when apt fails (no network), it
says so in one line and the set-up goes on: the browser test then skips with a loud reason, and
fails under ``CI=true``, where the set-up must have installed it.

    python3 lander_tools/system_packages.py        # what setup_env's hook runs
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

#: executable -> Debian package providing it.
PACKAGES: dict[str, str] = {"chromium": "chromium"}
LOG = Path(__file__).resolve().parent.parent / ".venv" / ".build" / "log" / "apt.log"


def missing() -> list[str]:
    """Debian packages whose executable is not on PATH."""
    return [pkg for exe, pkg in PACKAGES.items() if shutil.which(exe) is None]


def ensure(say: Callable[[str], None]) -> bool:
    """Install the missing packages if possible; True when all are present afterwards. Never raises."""
    need = missing()
    if not need:
        return True
    if os.geteuid() != 0 or shutil.which("apt-get") is None:
        say(f"not installing {' '.join(need)} (needs root and apt-get): the browser test will skip "
            "(and fail under CI=true)")
        return False
    say(f"installing {' '.join(need)} with apt-get for the browser test (log: {LOG})")
    LOG.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    with open(LOG, "a") as log:
        for cmd in (["apt-get", "update"], ["apt-get", "install", "-y", "--no-install-recommends", *need]):
            log.write(f"$ {' '.join(cmd)}\n")
            log.flush()
            try:
                rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, timeout=900)
            except (OSError, subprocess.TimeoutExpired) as exc:
                rc = -1
                log.write(f"{exc}\n")
            if rc != 0:
                say(f"apt-get failed (exit {rc}; see {LOG}): {' '.join(need)} not installed, the browser test will skip")
                return False
    still = missing()
    if still:
        say(f"apt-get ran but {' '.join(still)} is still missing (see {LOG})")
    return not still


def main() -> int:
    return 0 if ensure(lambda m: print(f"[dev] {m}", file=sys.stderr, flush=True)) else 1


if __name__ == "__main__":
    sys.exit(main())
