"""Choosing the plan to execute without the judge (beyond the paper).

The paper scores a scene by its best approach angle, which only the Bullet judge can pick. A
robot executes one plan, so each planner ranks its own candidates by what it knows: the
baseline by its kinematic cost at the end of the path optimisation (Sec. IV: w_static_hull x
c_static_hull + w_vel x c_vel), the physics planner by the objective in phi of the path it
chose (``details["select"]``; for plans made before that choice
existed, its last phi stage's final objective; with neither - no phi stage and no choice in
phi - the baseline's score of the path it started from, ``details["start_score"]``), the
push planner by its chosen path's P(success) in phi (`_push_score`). Lower is better.
"""

from __future__ import annotations

from drake_clutter.common.config import BaselineConfig
from drake_clutter.trajectory import Candidate

# details["chosen"] of a push candidate whose search's pick reads no grasp in phi: the
# baseline's own path is returned instead (``push_search.fallback``)
FALLBACK = "baseline"


def selection_score(planner: str, details: dict, baseline: BaselineConfig | None = None
                    ) -> float | None:
    """The score ``planner`` ranks a candidate by from its ``details`` (module docstring; the
    baseline's weights from ``baseline``); None where the record is missing."""
    if planner == "baseline":
        weights = baseline or BaselineConfig()
        if "c_vel" not in details:
            return None
        return (weights.w_static_hull * float(details.get("c_static_hull", [0.0])[-1])
                + weights.w_vel * float(details["c_vel"][-1]))
    if planner == "push":
        return _push_score(details)
    select = details.get("select") or {}
    value = (select.get("objectives") or {}).get(select.get("chosen"))
    if not select:
        stages = details.get("stages") or {}
        last = stages.get("full") or stages.get("sphere") or {}
        value = (last.get("cost_history") or [None])[-1]
        if value is None:
            value = details.get("start_score")
    return None if value is None else float(value)


def selected_index(candidates: list[Candidate], baseline: BaselineConfig | None = None
                   ) -> int | None:
    """The index of the usable candidate with the lowest `selection_score` (ties to the
    first), or None when no usable candidate has a score."""
    best, best_score = None, None
    for i, candidate in enumerate(candidates):
        if not candidate.ok:
            continue
        score = selection_score(candidate.planner, candidate.details or {}, baseline)
        if score is not None and (best_score is None or score < best_score):
            best, best_score = i, score
    return best


def _push_score(details: dict) -> float | None:
    """The push planner's score of its chosen path: minus its P(success) in phi, plus a
    hundredth of its expected grade (ties); -1 for a clear straight path (no search: such
    paths succeed in about 99 % of the judge's replays); 0.04 for the baseline's own path
    returned as the fallback (P(success) 0 and the worst grade in phi)."""
    if details.get("clear"):
        return -1.0
    if details.get("chosen") == FALLBACK:  # nothing read a grasp in phi
        return 0.04
    search = details.get("search") or {}
    verdict = (search.get("verdicts") or {}).get(details.get("chosen"))
    if verdict is None:
        return None
    return -float(verdict["p_success"]) + 0.01 * float(verdict["expected_grade"])
