"""What the rearrange planner did at one approach angle (`RearrangeRecord`), and its score.

Stored as the candidate's ``details``: ``chosen`` ("push": the push planner's answer returned
as it was; "room<i>": the i-th sequence of pushes found, then the reach), ``why`` (why the push
answer stands: "clear", "no reach", "no room", "not accepted", "veto", "budget"), ``crowd``
(the boxes the reach's region entered at rest, name -> m), ``moves`` (the chosen sequence's
pushes, `actions.Move.to_data`), ``search`` (`search.RoomSearch.to_data`), ``verdicts`` (per
judged path: P(success), expected grade, classes per member), ``veto``, ``budget`` and ``push``
(the push planner's own details, kept whole).
"""

from __future__ import annotations

from dataclasses import dataclass, field

PUSH = "push"  # details["chosen"] where the push planner's answer is returned unchanged
_KEYS = ("chosen", "why", "crowd", "moves", "search", "verdicts", "veto", "budget", "push")


@dataclass(frozen=True)
class RearrangeRecord:
    """A rearrange candidate's record (module docstring); absent fields are empty."""

    chosen: str = PUSH
    why: str = ""
    crowd: dict = field(default_factory=dict)
    moves: tuple[dict, ...] = ()
    search: dict = field(default_factory=dict)
    verdicts: dict = field(default_factory=dict)
    veto: dict = field(default_factory=dict)
    budget: dict = field(default_factory=dict)
    push: dict = field(default_factory=dict)

    @classmethod
    def from_details(cls, details: dict) -> RearrangeRecord:
        """The record of a candidate's ``details`` (stored or fresh)."""
        return cls(chosen=str(details.get("chosen", PUSH)), why=str(details.get("why", "")),
                   crowd=dict(details.get("crowd") or {}),
                   moves=tuple(details.get("moves") or ()),
                   search=dict(details.get("search") or {}),
                   verdicts=dict(details.get("verdicts") or {}),
                   veto=dict(details.get("veto") or {}), budget=dict(details.get("budget") or {}),
                   push=dict(details.get("push") or {}))

    def to_details(self) -> dict:
        """The record as a candidate's ``details`` (JSON-ready), the inverse of
        `from_details`."""
        return {k: (list(v) if isinstance(v, tuple) else v)
                for k in _KEYS if (v := getattr(self, k)) not in ("", {}, ())} | {
                    "chosen": self.chosen}

    @property
    def rearranged(self) -> bool:
        """Whether the returned plan pushes boxes aside before the reach."""
        return self.chosen != PUSH

    @property
    def bent(self) -> bool:
        """Whether the returned path is not a straight line (pushes first, or a bent reach)."""
        return self.rearranged or "/" in str(self.push.get("chosen", ""))

    @property
    def label(self) -> str:
        """The returned plan in a few words (for titles and tables)."""
        if self.rearranged:
            return f"{len(self.moves)} pushes, then the reach"
        return f"the push planner's path ({self.why})" if self.why else "the push planner's path"

    def histories(self) -> dict[str, dict]:
        """No iLQR histories."""
        return {}

    def score(self) -> float | None:
        """The rank of a rearranged candidate, lower first: minus its P(success) in phi plus a
        hundredth of its expected grade; None where the push answer stands (the registry then
        asks the push planner for its own score of ``push``)."""
        verdict = self.verdicts.get(self.chosen) if self.rearranged else None
        if verdict is None:
            return None
        return -float(verdict["p_success"]) + 0.01 * float(verdict["expected_grade"])
