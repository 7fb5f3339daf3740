"""docs/seed-tasks.md, run as a student types it: every command of its ``sh`` blocks, in page order.

Each ``./dev VERB ARGS`` line runs as ``python -m lander_tools.cli VERB ARGS`` (the project's own
entry point, which ``./dev`` runs inside the environment) in one scratch folder, the commands
exactly as written (their short ``--duration`` values are on the page). A command must exit 0, or
with the code its comment names (``# crashes: exit code 1``: a crash is the lesson there). A block
whose first command is a ``fly`` followed by verbs is a live session: the flight runs as a child
process, the verbs run once it publishes states past t = 0.5 s (an event waited for with a
timeout), each must exit 0, and the flight must still be flying after the last one.

A ``text`` block quotes output: each of its lines must be in what the ``sh`` block before it
printed (runs of spaces count as one). The flights quoted are deterministic (lockstep with an
autopilot, or the simulator alone, whose core is deterministic: docs/reliability.md), so the quoted
figures are exact, not approximate.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import rosutil
from lander_ros.stamps import stamp_to_seconds
from lander_tools.live.link import FlightLink
from lander_tools.live.wsclient import wait_until

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "seed-tasks.md"
#: verbs that act on a running flight: after a ``fly`` in the same block they make it a live session
LIVE_VERBS = {"pause", "resume", "step", "throttle", "stabiliser", "parachute", "demand", "wind", "switch",
              "reset", "echo", "topics"}
#: [s] one command's limit: the page's longest flight (one orbit, 8000 s at --speed 0) takes ~25 s
COMMAND_TIMEOUT = 240.0
#: [s] a live flight's start-up (two processes, discovery, reset) on a loaded 2-core machine
START_TIMEOUT = 90.0


@dataclass
class Command:
    argv: list[str]  # after ./dev
    exit_code: int
    line: str


@dataclass
class Block:
    number: int
    heading: str
    commands: list[Command]
    quoted: list[str] = field(default_factory=list)  # output lines the page quotes after it

    @property
    def live(self) -> bool:
        return (len(self.commands) > 1 and self.commands[0].argv[0] == "fly"
                and all(c.argv[0] in LIVE_VERBS for c in self.commands[1:]))


def parse_command(line: str) -> Command:
    words = shlex.split(line, comments=True)
    assert words and words[0] == "./dev" and len(words) > 1, f"not a './dev VERB ...' command: {line!r}"
    comment = line.split("#", 1)[1] if "#" in line else ""
    code = re.search(r"exit code (\d+)", comment)
    return Command(words[1:], int(code.group(1)) if code else 0, line.strip())


def page_blocks(text: str) -> list[Block]:
    """The page's ``sh`` blocks in order, each with the ``text`` blocks that follow it."""
    blocks: list[Block] = []
    heading = ""
    fence = re.compile(r"^(?P<indent> *)```(?P<lang>\w*)\n(?P<body>.*?)^(?P=indent)```", re.MULTILINE | re.DOTALL)
    pos = 0
    for m in fence.finditer(text):
        for h in re.findall(r"^#+ (.*)$", text[pos:m.start()], re.MULTILINE):
            heading = h
        pos = m.end()
        indent = len(m.group("indent"))
        lines = [ln[indent:] for ln in m.group("body").splitlines()]
        if m.group("lang") == "sh":
            commands = [parse_command(ln) for ln in lines if ln.strip()]
            blocks.append(Block(len(blocks) + 1, heading, commands))
        elif m.group("lang") == "text":
            assert blocks, "a text block before any sh block"
            blocks[-1].quoted += [ln for ln in lines if ln.strip()]
    return blocks


BLOCKS = page_blocks(PAGE.read_text())


def squash(s: str) -> str:
    return " ".join(s.split())


def lander(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lander_tools.cli", *argv], cwd=cwd, capture_output=True,
                          text=True, timeout=COMMAND_TIMEOUT, env=dict(os.environ, PYTHONPATH=str(REPO)))


def wait_states(fly: rosutil.ChildProcess) -> None:
    """Wait until the flight publishes a state past t = 0.5 s (the launcher has reset and resumed
    it); RuntimeError with its output if it exits first."""
    def alive() -> None:
        if fly.returncode is not None:
            raise RuntimeError(f"the flight exited ({fly.returncode}):\n{fly.output()[-4000:]}")

    times: list[float] = []
    lock = threading.Lock()

    def seen(msg) -> None:
        with lock:
            times.append(stamp_to_seconds(msg.header.stamp))

    with FlightLink("test_seed_tasks_page") as link:
        wait_until(lambda: alive() or "/lander/state" in dict(link.topics()), START_TIMEOUT, "the state topic")
        link.subscribe("/lander/state", "lander_interfaces/msg/LanderState", seen, depth=10)
        wait_until(lambda: alive() or (times and times[-1] > 0.5), START_TIMEOUT, "a state after t = 0.5 s")


def run_block(block: Block, cwd: Path) -> list[str]:
    """Run one block's commands; the failures, one line each (with the command's output)."""
    failures: list[str] = []
    output = ""
    if block.live:
        fly = rosutil.ChildProcess(["-m", "lander_tools.cli", *block.commands[0].argv], cwd=cwd, name="fly",
                                   env=dict(os.environ, PYTHONPATH=str(REPO)))
        try:
            wait_states(fly)
            for c in block.commands[1:]:
                r = lander(c.argv, cwd)
                output += r.stdout + r.stderr
                if r.returncode != c.exit_code:
                    failures.append(f"{c.line}: exit {r.returncode}, expected {c.exit_code}\n{r.stdout}{r.stderr}")
            if fly.returncode is not None:
                failures.append(f"{block.commands[0].line}: ended during the session ({fly.returncode})\n"
                                f"{fly.output()[-4000:]}")
        except RuntimeError as err:
            failures.append(f"{block.commands[0].line}: {err}")
        finally:
            fly.close()
    else:
        for c in block.commands:
            r = lander(c.argv, cwd)
            output += r.stdout + r.stderr
            if r.returncode != c.exit_code:
                failures.append(f"{c.line}: exit {r.returncode}, expected {c.exit_code}\n{r.stdout}{r.stderr}")
    printed = squash(output)
    for line in block.quoted:
        if squash(line) not in printed:
            failures.append(f"quoted output not printed: {line.strip()!r}\n--- the block printed:\n{output}")
    return failures


@pytest.fixture(scope="module")
def page_run(module_ros_domain: int, tmp_path_factory: pytest.TempPathFactory) -> dict[int, list[str]]:
    """Every block run once, in page order, in one folder (later blocks read earlier blocks' bags
    and gains files); the page's ``flights/`` paths are the repository's."""
    cwd = tmp_path_factory.mktemp("student")
    (cwd / "flights").symlink_to(REPO / "flights")
    return {block.number: run_block(block, cwd) for block in BLOCKS}


def test_the_page_names_a_command_for_every_task_and_quotes_what_it_prints() -> None:
    text = PAGE.read_text()
    for task in ("Task 1", "Task 2", "Tasks 3 and 4", "Lander task 1", "Lander task 2", "Lander task 3",
                 "Seed 1 extensions", "Altitude task 1", "Altitude task 2", "Altitude task 3", "Altitude task 4",
                 "Attitude task 1", "Attitude task 2", "Attitude task 3", "Seed 2 extensions"):
        section = re.search(rf"^### {re.escape(task)}\b.*?(?=^##)", text + "\n##", re.MULTILINE | re.DOTALL)
        assert section and "```sh" in section.group(0), f"no command for {task!r}"
    assert sum(len(b.quoted) for b in BLOCKS) >= 15
    assert any(b.live for b in BLOCKS)
    assert "docs/seed-tasks.md" in (REPO / "README.md").read_text()


@pytest.mark.parametrize("block", BLOCKS, ids=lambda b: f"{b.number}-{b.commands[0].argv[0]}-{b.heading[:30]}")
def test_each_block_runs_as_written_and_prints_what_the_page_quotes(block: Block, page_run) -> None:
    failures = page_run[block.number]
    assert not failures, f"docs/seed-tasks.md, '{block.heading}':\n" + "\n".join(failures)
