"""The straight starts of an approach angle (beyond the paper): the baseline's path at each
grasp height of ``starts.grasp_heights`` and at the angle turned by each yaw offset of
``starts.approach_offsets``, beside the baseline's own (``baseline.grasp_height_fraction``).

Sec. IV fixes the grasp height; which height keeps off the boxes beside the target depends on
the scene, so the planners that see the boxes (the push planner, and Sec. V's height choice)
start from all of them. Each start is the baseline planned at the same angle index with the
same IK seeds (`baseline.plan_angle`), named in records by `start_key`.

Where no start plans at the angle (the baseline's path fails IK, the optimiser or the dense
shelf check at every height), `turned_starts` turns the line toward the shelf's axis
(``starts.recovery_turns``) until one does: at the steep angles a refrigerator's side wall
leaves no start pose or pre-grasp pose clear of the shelf.
"""

from __future__ import annotations

import time

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.trajectory import Candidate


def start_key(fraction: float, offset: float) -> str:
    """A start's name in the record: its grasp height fraction, and its approach yaw offset
    (rad) where it has one ("0.7", "0.7 yaw -0.06")."""
    return f"{fraction:g}" if offset == 0.0 else f"{fraction:g} yaw {offset:+g}"


def height_candidates(context: PlanningContext, candidate: Candidate,
                      deadline: Deadline | None = None) -> dict[tuple[float, float], Candidate]:
    """The start ``candidate`` (the baseline's, at ``baseline.grasp_height_fraction``) and the
    baseline planned at each fraction of ``starts.grasp_heights`` at the same angle, then at
    the angle turned by each yaw offset of ``starts.approach_offsets`` (rad) at every
    fraction, by (fraction, offset) in that order (the start's first); only candidates with a
    trajectory ("ok"): a ``candidate`` that failed is left out and the others are planned all
    the same. The solvers per fraction are the context's (`baseline_at`). Once ``deadline``
    has passed no further start is planned (each plan is an indivisible step)."""
    config = context.config
    offsets = [0.0] + [o for o in config.starts.approach_offsets if o != 0.0]
    keys = [(f, o) for o in offsets for f in _fractions(config)]
    first = (config.baseline.grasp_height_fraction, 0.0)
    out = {first: candidate} if candidate.ok else {}
    return out | _plan_starts(context, candidate, [k for k in keys if k != first], deadline)


def turned_starts(context: PlanningContext, candidate: Candidate,
                  deadline: Deadline | None = None) -> dict[tuple[float, float], Candidate]:
    """The straight starts of a failed ``candidate``'s angle turned toward alpha = 0 by each
    turn of ``starts.recovery_turns`` (rad) in order, at every fraction as in
    `height_candidates`: those of the first turn at which any plans, by (fraction, offset),
    offset = -sign(alpha) x turn (rad); empty if none does or ``deadline`` passes first."""
    config = context.config
    sign = float(np.sign(candidate.alpha))
    contexts: dict = {}
    for turn in config.starts.recovery_turns:
        keys = [(f, -sign * turn) for f in _fractions(config)]
        out = _plan_starts(context, candidate, keys, deadline, contexts)
        if out:
            return out
    return {}


def planned_starts(context: PlanningContext, candidate: Candidate,
                   deadline: Deadline | None = None) -> dict[tuple[float, float], Candidate]:
    """The straight starts of ``candidate``'s angle (`height_candidates`); for a failed
    ``candidate`` with none, those of the line turned toward alpha = 0 (`turned_starts`)."""
    found = height_candidates(context, candidate, deadline)
    if not found and not candidate.ok:
        found = turned_starts(context, candidate, deadline)
    return found


def _fractions(config) -> list[float]:
    """The grasp height fractions of the starts: the baseline's, then ``starts.grasp_heights``."""
    base = config.baseline.grasp_height_fraction
    return [base] + [f for f in config.starts.grasp_heights if f != base]


def angle_index(candidate: Candidate, config: Config) -> int:
    """The index of ``candidate``'s approach angle among `approach.approach_angles`: the one it
    carries, else (a hand-made candidate) the nearest angle's."""
    if candidate.index is not None:
        return candidate.index
    return int(np.argmin(np.abs(approach_angles(config.baseline) - candidate.alpha)))


def _plan_starts(context: PlanningContext, candidate: Candidate, keys: list,
                 deadline: Deadline | None, contexts: dict | None = None) -> dict:
    """The baseline planned at ``candidate``'s angle turned by each (fraction, offset) of
    ``keys``, in order, the ok ones; one prepared solver per fraction (``contexts``), so that a
    later offset starts from the IK solutions of the earlier ones, as the baseline's angles do."""
    index = angle_index(candidate, context.config)
    contexts = {} if contexts is None else contexts
    out = {}
    for fraction, offset in keys:
        if deadline is not None and deadline.spend("heights"):
            return out
        tic = time.monotonic()
        if fraction not in contexts:
            contexts[fraction] = context.baseline_at(fraction)
        found = baseline.plan_angle(contexts[fraction], candidate.alpha + offset, index)
        if deadline is not None:
            deadline.timed(time.monotonic() - tic)
        if found.ok:
            out[(fraction, offset)] = found
    return out
