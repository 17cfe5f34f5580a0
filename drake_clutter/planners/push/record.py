"""What the push planner did at one approach angle (`PushRecord`), and the score it ranks its
candidates by.

The planner (`planner.push_candidate`) builds its record and stores it as the candidate's
``details`` (`PushRecord.to_details`); a stored one reads back with `PushRecord.from_details`.
The keys: ``initialization`` (the planner the start came from), ``clear`` (the straight starts
that keep off the boxes; the first is the plan), ``chosen`` (the name of the returned path: a
start ``"<height>"``, a bent member ``"<start>/<draw>"``, or `FALLBACK`), ``search`` (the
search's record: ``verdicts`` per judged path, ``counts``, ``chosen``, ``best_start``),
``recovered`` (the baseline's failure a turned or other-height start replaced), ``budget``
(what the time budget cut). When no start planned at the angle, the candidate is the
baseline's failure and its initializing planner's record is kept beside these keys
(``start``, written at the top level as stores have it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

# details["chosen"] of a push candidate whose search's pick reads no grasp in phi: the
# baseline's own path is returned instead (``push_search.fallback``)
FALLBACK = "baseline"
# the score of a clear straight start (no search: such paths succeed in about 99 % of the
# judge's replays) and of the fallback (P(success) 0 and the worst grade in phi)
CLEAR_SCORE, FALLBACK_SCORE = -1.0, 0.04
# the record's own keys in ``details``
_KEYS = ("initialization", "clear", "search", "chosen", "budget", "recovered")


@dataclass(frozen=True)
class PushRecord:
    """A push candidate's record (module docstring); fields absent from ``details`` are empty."""

    chosen: str = ""
    clear: tuple[str, ...] = ()
    search: dict = field(default_factory=dict)
    recovered: dict = field(default_factory=dict)
    budget: dict = field(default_factory=dict)
    initialization: str = ""
    start: dict = field(default_factory=dict)

    @classmethod
    def from_details(cls, details: dict) -> PushRecord:
        """The record of a candidate's ``details`` (stored or fresh)."""
        return cls(chosen=str(details.get("chosen", "")), clear=tuple(details.get("clear", ())),
                   search=dict(details.get("search") or {}),
                   recovered=dict(details.get("recovered") or {}),
                   budget=dict(details.get("budget") or {}),
                   initialization=str(details.get("initialization", "")),
                   start={k: v for k, v in details.items() if k not in _KEYS})

    @classmethod
    def failed(cls, start_details: dict, budget: dict) -> PushRecord:
        """The record of a candidate that planned no start: its initializing planner's
        ``start_details`` kept, what the ``budget`` cut."""
        return cls(budget=budget, start=dict(start_details))

    def to_details(self) -> dict:
        """The record as a candidate's ``details`` (JSON-ready; empty fields left out), the
        inverse of `from_details`."""
        out = {"initialization": self.initialization, "clear": list(self.clear),
               "search": self.search, "chosen": self.chosen, "budget": self.budget,
               "recovered": self.recovered}
        return self.start | {k: v for k, v in out.items() if v}

    @property
    def bent(self) -> bool:
        """Whether the returned path is a bent member of the family, not a straight start."""
        return "/" in self.chosen

    @property
    def fallback(self) -> bool:
        """Whether the baseline's own path was returned in place of the search's pick."""
        return self.chosen == FALLBACK

    @property
    def label(self) -> str:
        """The returned path in a few words (for titles and tables)."""
        return f"path {self.chosen}" if self.chosen else "no path"

    def histories(self) -> dict[str, dict]:
        """No iLQR histories: the search samples."""
        return {}

    def verdict(self, name: str | None = None) -> dict | None:
        """The search's verdict summary (``p_success``, ``expected_grade``, ``kinds``) of the
        path ``name`` (default: the returned one); None when it was not judged."""
        return (self.search.get("verdicts") or {}).get(self.chosen if name is None else name)

    def score(self) -> float | None:
        """The push planner's rank of the candidate, lower first: minus its chosen path's
        P(success) in phi plus a hundredth of its expected grade (ties); `CLEAR_SCORE` for a
        clear straight start, `FALLBACK_SCORE` for the fallback; None when nothing was judged."""
        if self.clear:
            return CLEAR_SCORE
        if self.fallback:
            return FALLBACK_SCORE
        verdict = self.verdict()
        if verdict is None:
            return None
        return -float(verdict["p_success"]) + 0.01 * float(verdict["expected_grade"])
