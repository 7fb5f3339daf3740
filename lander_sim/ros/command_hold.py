"""The simulator's zero-order hold of the last throttle command, with a staleness limit in sim time
(docs/sim_node.md, parameter ``command_timeout``). Plain Python, no rclpy."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class CommandHold:
    """When the held command was accepted, and whether it has gone stale.

    ``timeout`` [s of sim time] is ``command_timeout``: a command older than that is stale and the
    throttles go to zero once; 0 (or less) holds the last command for good."""

    timeout: float = 0.0
    accepted_at: float | None = None  # sim time [s] the held command was accepted; None: none yet
    stale: bool = False
    #: sim time [s] a user's step began (None: the flight runs on its own). Steps asked for by the
    #: user (``/lander/step``, ``/lander/run_until``) go by in one service call, with no chance for
    #: anyone to answer them: they fly the held command and do not age it.
    stepping_from: float | None = None

    def accepted(self, t: float) -> None:
        """A command was accepted at sim time ``t``: it is held, fresh."""
        self.accepted_at, self.stale = t, False

    def clear(self) -> None:
        """No command held (a reset or a new scene)."""
        self.accepted_at, self.stale = None, False

    def step_begins(self, t: float) -> None:
        """A user's step starts at sim time ``t``: until :meth:`step_ends` the command does not age."""
        self.stepping_from = t

    def step_ends(self, t: float) -> None:
        """The user's step ended at sim time ``t``: the held command is as old as it was when the
        step began (no command is taken inside the service call that steps)."""
        if self.stepping_from is not None and self.accepted_at is not None and not self.stale:
            self.accepted_at += t - self.stepping_from
        self.stepping_from = None

    def expired(self, t: float) -> float | None:
        """The held command's age [s] at sim time ``t`` if it has just gone stale (once per command:
        the caller zeroes the throttles), else None; never during a user's step."""
        if self.timeout <= 0.0 or self.accepted_at is None or self.stale or self.stepping_from is not None:
            return None
        age = t - self.accepted_at
        if age > self.timeout:
            self.stale = True
            return age
        return None
