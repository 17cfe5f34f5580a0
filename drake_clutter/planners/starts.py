"""The straight starts of an approach angle (beyond the paper): the baseline's path at each
grasp height of ``physics.grasp_heights`` and at the angle turned by each yaw offset of
``physics.approach_offsets``, beside the baseline's own (``baseline.grasp_height_fraction``).

Sec. IV fixes the grasp height; which height keeps off the boxes beside the target depends on
the scene, so the planners that see the boxes (the push planner, and Sec. V's height choice)
start from all of them. Each start is the baseline planned at the same angle index with the
same IK seeds (`baseline.plan_angle`), named in records by `start_key`.
"""

from __future__ import annotations

import time

import numpy as np

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
    baseline planned at each fraction of ``physics.grasp_heights`` at the same angle, then at
    the angle turned by each yaw offset of ``physics.approach_offsets`` (rad) at every
    fraction, by (fraction, offset) in that order (the start's first); only candidates with a
    trajectory ("ok"). The solvers per fraction are the context's (`baseline_at`). Once
    ``deadline`` has passed no further start is planned (each plan is an indivisible step)."""
    config = context.config
    alphas = approach_angles(config.baseline)
    index = int(np.argmin(np.abs(alphas - candidate.alpha)))
    base = config.baseline.grasp_height_fraction
    fractions = [base] + [f for f in config.physics.grasp_heights if f != base]
    offsets = [0.0] + [o for o in config.physics.approach_offsets if o != 0.0]
    contexts, out = {}, {}
    for offset in offsets:
        for fraction in fractions:
            if (fraction, offset) == (base, 0.0):
                out[(base, 0.0)] = candidate
                continue
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
