"""Choosing the plan to execute without the judge (beyond the paper).

The paper scores a scene by its best approach angle, which only the Bullet judge can pick. A
robot executes one plan, so each planner ranks its own candidates by what it knows
(`registry.Planner.score`, lower is better): the baseline by its kinematic cost at the end of
the path optimisation (Sec. IV), the physics planner by the objective in phi of the path it
chose, the push planner by its chosen path's P(success) in phi. This module only ranks.
"""

from __future__ import annotations

from drake_clutter.common.config import Config
from drake_clutter.planners.registry import get_planner
from drake_clutter.trajectory import Candidate


def selection_score(planner: str, details: dict, config: Config | None = None) -> float | None:
    """The score ``planner`` ranks a candidate by from its ``details`` (`Planner.score`, its
    settings from ``config``); None where the record is missing."""
    return get_planner(planner).score(details or {}, config)


def selected_index(candidates: list[Candidate], config: Config | None = None) -> int | None:
    """The index of the usable candidate with the lowest `selection_score` (ties to the
    first), or None when no usable candidate has a score."""
    best, best_score = None, None
    for i, candidate in enumerate(candidates):
        if not candidate.ok:
            continue
        score = selection_score(candidate.planner, candidate.details, config)
        if score is not None and (best_score is None or score < best_score):
            best, best_score = i, score
    return best
