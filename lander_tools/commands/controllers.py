"""`lander controllers`: the controllers `lander fly --controller` accepts, and their parameters.

    lander controllers                  every controller, one line each
    lander controllers NAME             its parameter table: name, default, unit, range, meaning
    lander controllers NAME --markdown  the same table as Markdown
    lander controllers --update-docs    regenerate the tables in docs/*.md

A doc carries a controller's table between a line ``<!-- params: NAME -->`` and a line
``<!-- /params -->``; the lines between are exactly ``lander controllers NAME --markdown``
(test/control/test_param_docs.py fails on drift, naming the doc and the controller).
"""
from __future__ import annotations

import argparse
import inspect
import re
import sys
from pathlib import Path

#: A generated block: its first line names the controller, its last closes it.
BLOCK_START = re.compile(r"^<!-- params: (?P<name>[A-Za-z0-9_.-]+) -->$")
BLOCK_END = "<!-- /params -->"
DOCS = Path(__file__).resolve().parents[2] / "docs"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", help="a controller's name: print its parameter table")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown (the docs' blocks)")
    parser.add_argument("--update-docs", action="store_true",
                        help="rewrite every '<!-- params: NAME -->' block in docs/*.md from the tables")


def markdown(name: str) -> str:
    """``lander controllers NAME --markdown`` (without the final newline); ValueError if ``name``
    is unknown or has no parameter table."""
    from lander_autopilot.controllers.registry import parameter_table

    table = parameter_table(name)
    if table is None:
        raise ValueError(f"controller {name!r} has no parameter table (its keywords: see 'lander controllers {name}')")
    return table.markdown()


def blocks(text: str) -> list[tuple[str, int, int]]:
    """The generated blocks of a doc: ``(controller, first line inside, line of the end marker)``
    (0-based line numbers); ValueError for a block that is never closed."""
    lines = text.split("\n")
    found: list[tuple[str, int, int]] = []
    i = 0
    while i < len(lines):
        m = BLOCK_START.match(lines[i])
        if m is None:
            i += 1
            continue
        try:
            end = lines.index(BLOCK_END, i + 1)
        except ValueError:
            raise ValueError(f"line {i + 1}: '<!-- params: {m['name']} -->' has no '{BLOCK_END}' after it") from None
        found.append((m["name"], i + 1, end))
        i = end + 1
    return found


def regenerate(text: str) -> str:
    """``text`` with every block's lines replaced by its controller's table."""
    lines = text.split("\n")
    for name, start, end in reversed(blocks(text)):
        lines[start:end] = markdown(name).split("\n")
    return "\n".join(lines)


def update_docs(docs: Path = DOCS) -> list[Path]:
    """Rewrite the blocks of every ``docs/*.md``; the docs changed."""
    changed = []
    for path in sorted(docs.glob("*.md")):
        text = path.read_text()
        new = regenerate(text)
        if new != text:
            path.write_text(new)
            changed.append(path)
    return changed


def _summary(factory: object) -> str:
    doc = inspect.getdoc(factory) or ""
    return doc.split("\n\n")[0].replace("\n", " ")


def run(args: argparse.Namespace) -> int:
    from lander_autopilot.controllers.registry import (
        BUILTINS,
        accepted_parameters,
        available_controllers,
        parameter_table,
    )

    if args.update_docs:
        for path in update_docs():
            print(f"updated {path.relative_to(DOCS.parent)}")
        return 0
    if args.name is None:
        names = available_controllers()
        width = max(len(n) for n in names)
        for n in names:
            print(f"{n:<{width}}  {_summary(BUILTINS[n]) if n in BUILTINS else '(plug-in)'}")
        return 0
    if args.markdown:
        print(markdown(args.name))
        return 0
    table = parameter_table(args.name)
    if table is not None:
        print(table.text())
        return 0
    keys = accepted_parameters(args.name)
    if keys is None:
        print(f"{args.name}: a plug-in that checks its own parameters", file=sys.stderr)
    else:
        print(f"{args.name}: keyword parameters (no table): {', '.join(keys) or '(none)'}")
    return 0
