"""Reading a user's YAML file (scene, parameters, sweep, scripted flight) with errors that name it.

Every configuration file goes through :func:`read_yaml`, so a missing file, a binary file and a
YAML syntax error give the same kind of one-line message everywhere: the file, then what is wrong.

A package of its own below every layer (it imports only PyYAML): the simulator's core reads its
scenes with it, ``lander_ros`` both nodes' parameter files and ``lander_tools`` sweeps and scripted
flights, and none of them has to import another's package for it (docs/architecture.md).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


def read_yaml(path: str | Path, what: str, error: type[ValueError]) -> Any:
    """The parsed content of ``path``; raises ``error`` (a ``ValueError`` subclass) naming the file.

    ``what`` says what the file should be (e.g. ``"scene file"``) for the unreadable case.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{p}: cannot read {what}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise error(f"{p}: not a text (UTF-8) file: byte {exc.start} is {exc.object[exc.start]:#04x}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(f"{p}: not valid YAML: {exc}") from None
