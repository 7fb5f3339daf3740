"""A recorded flight's span: when its states start and end, and whether any is missing.

Plain numpy (no rclpy, no bag reader): ``lander analyse`` feeds it the ``/lander/state`` sequence
numbers and stamps of each bag. A whole flight (docs/flying.md, "A flight's span") starts with
state 1 at t = 0 and numbers its states 1, 2, ... N without a gap; the simulator restarts the
numbering at every reset, so a restart in the middle of a bag means it holds more than one flight.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Float rounding of a sim time through a ROS stamp (integer ns) [s].
_T_EPS = 1e-9


@dataclass(frozen=True)
class BagSpan:
    """The states of one bag: first and last sim time [s], count, and what breaks the sequence."""

    states: int
    t_first: float = float("nan")
    t_last: float = float("nan")
    first_sequence: int = 0
    #: ``(after, next)`` sequence numbers around each gap (states missing between them).
    gaps: list[tuple[int, int]] = field(default_factory=list)
    #: Positions where the numbering starts again at 1 (a reset inside the bag).
    restarts: int = 0

    @property
    def missing(self) -> int:
        """States missing inside the sequence (the gaps' sizes summed)."""
        return sum(b - a - 1 for a, b in self.gaps)

    def problems(self) -> list[str]:
        """What keeps this bag from holding one whole flight, one phrase each (empty: none)."""
        if self.states == 0:
            return ["no state in the bag"]
        out = []
        if abs(self.t_first) > _T_EPS or self.first_sequence != 1:
            out.append(f"does not start at t = 0 (first state {self.first_sequence} at t = {self.t_first:.3f} s)")
        if self.gaps:
            shown = ", ".join(f"{a}->{b}" for a, b in self.gaps[:5]) + (" ..." if len(self.gaps) > 5 else "")
            out.append(f"{self.missing} states missing in {len(self.gaps)} gaps ({shown})")
        if self.restarts:
            out.append(f"the sequence restarts {self.restarts} times (more than one flight, or a reset)")
        return out

    def describe(self) -> str:
        """One line: the span, and what is wrong with it if anything."""
        if self.states == 0:
            return "no states"
        text = f"t = {self.t_first:.3f} to {self.t_last:.3f} s, {self.states} states"
        bad = self.problems()
        return text + ("; " + "; ".join(bad) if bad else "; whole (from t = 0, no gap)")


def bag_span(t: np.ndarray, sequence: np.ndarray) -> BagSpan:
    """The span of states stamped ``t`` [s] with sequence numbers ``sequence``, in bag order."""
    t, seq = np.asarray(t, dtype=float), np.asarray(sequence, dtype=np.int64)
    if seq.size == 0:
        return BagSpan(0)
    step = np.diff(seq)
    restarts = int(np.count_nonzero(seq[1:] == 1))
    jump = np.flatnonzero((step != 1) & (seq[1:] != 1))
    gaps = [(int(seq[i]), int(seq[i + 1])) for i in jump]
    return BagSpan(int(seq.size), float(t[0]), float(t[-1]), int(seq[0]), gaps, restarts)
