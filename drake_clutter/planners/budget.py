"""A planner's wall-time budget on one initialization (one baseline candidate it refines).

The budget counts from the planner's first step on the candidate (the baseline's own planning
of the angle is the baseline's time). Work is cut only between indivisible steps: a planner
asks `Deadline.spend` before each, and a step that starts just before the deadline runs to its
end, so a planner overruns its budget by at most one such step and its own book-keeping.
`Deadline.at` is a `time.monotonic` value, the same clock in every process of the machine, so
worker processes can be handed it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from drake_clutter.solvers.descent import past  # the solvers' deadline test, the same clock


@dataclass
class Deadline:
    """``seconds`` of wall time from creation (None: no limit), what was cut when it passed,
    and the longest indivisible step timed under it."""

    seconds: float | None
    start: float = field(default_factory=time.monotonic)
    cut: list[str] = field(default_factory=list)
    longest_step: float = 0.0  # s

    @property
    def at(self) -> float | None:
        """The `time.monotonic` value (s) at which the budget is spent; None: never."""
        return None if self.seconds is None else self.start + self.seconds

    def passed(self) -> bool:
        """Whether the budget is spent."""
        return past(self.at)

    def spend(self, step: str) -> bool:
        """True (and ``step`` recorded as cut, once) when the budget is spent: the caller leaves
        ``step`` out."""
        if self.passed():
            if step not in self.cut:
                self.cut.append(step)
            return True
        return False

    def timed(self, seconds: float) -> None:
        """Notes an indivisible step's duration (s)."""
        self.longest_step = max(self.longest_step, seconds)

    def record(self) -> dict:
        """JSON-ready: the budget (s), the wall time so far (s), whether it was spent, the
        steps cut and the longest indivisible step (s)."""
        return {"budget": self.seconds, "wall_time": time.monotonic() - self.start,
                "spent": bool(self.cut), "cut": list(self.cut),
                "longest_step": self.longest_step}
