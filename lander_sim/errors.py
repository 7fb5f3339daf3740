"""Errors of the simulator core, each a ``ValueError`` subclass with a message that names what was wrong."""
from __future__ import annotations


class InputError(ValueError):
    """A command given to a running simulation was rejected (bad throttle, wind, ...).

    The message names the field and the offending value; the state is left untouched.
    """
