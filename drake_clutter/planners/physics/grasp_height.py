"""Sec. V's start at each approach angle (beyond the paper): one of the straight starts
(`starts.height_candidates`: the baseline's path at each grasp height of
``starts.grasp_heights`` and yaw offset of ``starts.approach_offsets``) begins the
pre-processing and stands as "baseline" in ``select``: the first that neither presses on a box's
top deeper than ``starts.press_tolerance`` nor enters a non-target box's side deeper than
``starts.side_tolerance`` (`geometry.path_depths`, the boxes at rest), else the first ranked by
(presses, enters a side). Why this rule: docs/decisions.md (``starts.grasp_heights``).
"""

from __future__ import annotations

from drake_clutter.planners.baseline import BaselineRecord
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import box_depths, contact_flags
from drake_clutter.planners.starts import height_candidates, start_key
from drake_clutter.trajectory import Candidate


def choose_height(context: PlanningContext, candidate: Candidate,
                  deadline: Deadline | None = None) -> tuple[Candidate, dict]:
    """The start among `height_candidates` of ``candidate`` (the baseline's; those planned
    before ``deadline``) chosen by the module's rule, and what was measured: per `start_key`,
    its height h (m), yaw offset (rad), press and side depths (m); the chosen key."""
    found = height_candidates(context, candidate, deadline)
    paths = {k: c.trajectory.q for k, c in found.items()}
    depths = box_depths(context.arm(), paths, context.config, context.scene.target)
    scores = contact_flags(depths, context.config)
    record = {start_key(*key): {"height": BaselineRecord.from_details(c.details).height,
                                "yaw_offset": key[1],
                                "press": depths[key][0], "side": depths[key][1]}
              for key, c in found.items()}
    chosen = min(found, key=lambda k: (*scores[k], list(found).index(k)))
    return found[chosen], {"rule": "clear", "candidates": record, "chosen": start_key(*chosen)}
