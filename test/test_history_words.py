"""The product speaks of what is and why, never of the history of the work: no tracked file names
a work item or a step of the work by its number (the word "issue" or "stop" and a number, or a
span "since" or "until" such a step). History lives in the commit messages. Every file ``git
ls-files`` lists is scanned (binary files skipped), and each hit is reported as ``file:line``."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Built from parts so that this file's own text holds no match.
_STEP, _ITEM = "st" + "op", "iss" + "ue"
HISTORY_WORDS = re.compile(
    rf"\b({_STEP}s?[- ][0-9]+|{_ITEM}[- ][0-9]+|since {_STEP}|until {_STEP})\b", re.IGNORECASE)


def history_hits(text: str) -> list[tuple[int, str]]:
    """``(line number, line)`` of each line of ``text`` holding a history word."""
    return [(n, line) for n, line in enumerate(text.splitlines(), 1) if HISTORY_WORDS.search(line)]


def tracked_text_files() -> list[Path]:
    """Every tracked file that is text (no NUL byte in it, valid UTF-8)."""
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    files = []
    for name in out.decode().split("\0"):
        path = REPO / name
        if not name or not path.is_file():  # a file deleted in the working tree but not yet in git
            continue
        data = path.read_bytes()
        if b"\0" in data:
            continue
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            continue
        files.append(path)
    return files


@pytest.mark.parametrize("line", [
    f"measured at {_STEP} 41", f"{_STEP.title()}s 43-44", f"as in {_ITEM} 45", f"{_ITEM.upper()} 7: a regression",
    f"0.95 until {_STEP} 41", f"the margin since {_STEP} 40", f"{_STEP} 3's figure", f"the {_ITEM}-14 yardstick",
])
def test_the_matcher_finds_a_history_word(line: str) -> None:
    assert history_hits(f"first line\n{line}\n") == [(2, line)]


@pytest.mark.parametrize("line", [
    "the fall stopped within 2 m", "a stop at 0.2 m/s", "nonstop 5 s", "issues 4 warnings",
    "stop_above 1.75 m", "tissue 5", "the issue's yardstick",
])
def test_the_matcher_leaves_plain_words(line: str) -> None:
    assert history_hits(line) == []


def test_a_new_file_naming_a_work_item_fails(tmp_path: Path) -> None:
    doc = tmp_path / "new.md"
    line = f"The margin ({_ITEM} 45) keeps the fall in the band."
    doc.write_text(f"# Guide\n\n{line}\n")
    assert history_hits(doc.read_text()) == [(3, line)]


def test_no_tracked_file_speaks_of_the_history_of_the_work() -> None:
    files = tracked_text_files()
    assert len(files) > 100  # the scan saw the tree
    hits = [f"{path.relative_to(REPO)}:{n}: {line.strip()}" for path in files for n, line in history_hits(
        path.read_text(encoding="utf-8"))]
    assert not hits, f"{len(hits)} lines speak of the work's history (say what is and why):\n" + "\n".join(hits)
