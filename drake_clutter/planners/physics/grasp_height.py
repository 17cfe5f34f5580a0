"""Choosing the grasp height and the approach line at each approach angle (beyond the paper).

Sec. IV fixes the grasp height h (``baseline.grasp_height_fraction`` of the target's height) and
the physics planner starts from the baseline's path at that height. Which height succeeds
depends on the scene (the boxes beside the target that the fingers or the palm would land on,
the part of the target the pads close on): on the probe tier the best of five heights per
initialization succeeds 0.08 more often than the fixed one, and no fixed height is better on
average (docs/log/physics_planner.md, 2026-11-26). The baseline cannot choose: it ignores the
boxes. The physics planner sees them. With ``physics.grasp_heights`` the baseline is planned at
each listed height too (the same angle and IK seeds), with ``physics.approach_offsets`` at the
angle turned by each offset too (a few degrees: the straight line into the pre-grasp passes the
target's neighbours elsewhere), and one path becomes the start of the physics planner's stages
(``physics.height_choice``):

- "press": the start unless its path presses on a box's top (`penetration.path_depths`, the
  judge's usual kinematic failure as a geometric check on the boxes at rest) and a listed
  one's does not, then the first such.
- "clear": as "press", but a listed one whose path also keeps off the other boxes' sides
  (`penetration.path_depths`: no side penetration deeper than ``physics.side_tolerance``, the
  target's excepted) comes first; the baseline ignores the boxes, and at some heights its line
  happens to pass them. On the probe tier, offline over the baseline's five heights, +0.049
  [+0.014, +0.091] in P(success) against the fixed height where "press" made +0.026 (8 and 5
  initializations up, none down; docs/log/physics_planner.md, 2026-11-26 evening).
- "phi": every path rolled out in each of phi's ensemble members (one phi per path: their
  starts differ), the judge's classes read on phi's state after the hold tail
  (`settled_class`, with the judge's own definitions from `scene.grading`) and averaged over
  the members as the robust judge averages its replays; the best mean class wins, ties to the
  start's height, then to the listed order. On the probe tier's two angles it was chosen on
  it gained +0.06 in P(success), on the other two -0.01: phi's classes rank heights at a coin.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from drake_clutter.common.config import Config, EvaluationConfig
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.physics.ensemble import member_rollouts
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.planners.physics.penetration import path_depths
from drake_clutter.planners.physics.phi_judge import box_fates
from drake_clutter.scene.grading import target_zone_reason
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate


def settled_class(scene: Scene, geometry: ArmGeometry, q_last: np.ndarray,
                  final: dict[str, np.ndarray] | None, evaluation: EvaluationConfig
                  ) -> float | None:
    """The judge's grade read on phi's boxes after the hold tail, as one number: class 0
    (success), 1 (partial success: an obstacle tipped past ``max_tilt``) or 2 (a box off the
    board, or the target not in the pre-grasp zone of the gripper at ``q_last``, the last knot
    (8,)), + 0.01 per box tipped or fallen. ``final``: the kept boxes' 13-number states
    (quaternion wxyz, position in W (m), ...); a box missing from it (phi held it frozen) is at
    rest where the scene put it. None where phi failed (``final`` None). Kinematic failures
    are not read: phi's arm is never stopped."""
    if final is None:
        return None
    names = [b.name for b in scene.boxes]
    p, R_WB, fallen, tipped = box_fates(scene, geometry, final, evaluation)
    X_WG = geometry.tool_jacobian(q_last)[0]
    i = names.index(scene.target)
    R_WG = X_WG.rotation().matrix()
    reason = target_zone_reason(R_WG.T @ (p[i] - X_WG.translation()), R_WG.T @ R_WB[i],
                                scene.target_box.size, float(q_last[7]), evaluation)
    others = [k for k, n in enumerate(names) if n != scene.target]
    grade = 2 if fallen.any() or reason else 1 if tipped[others].any() else 0
    return grade + 0.01 * int(fallen.sum() + tipped.sum())


def start_key(fraction: float, offset: float) -> str:
    """A start's name in the record: its grasp height fraction, and its approach yaw offset
    (rad) where it has one ("0.7", "0.7 yaw -0.06")."""
    return f"{fraction:g}" if offset == 0.0 else f"{fraction:g} yaw {offset:+g}"


def height_candidates(scene: Scene, candidate: Candidate, config: Config
                      ) -> dict[tuple[float, float], Candidate]:
    """The start ``candidate`` (the baseline's, at ``baseline.grasp_height_fraction``) and the
    baseline planned at each fraction of ``physics.grasp_heights`` at the same angle, then at
    the angle turned by each yaw offset of ``physics.approach_offsets`` (rad) at every
    fraction, by (fraction, offset) in that order (the start's first); only candidates with a
    trajectory ("ok")."""
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
            if fraction not in contexts:
                cfg = replace(config.baseline, grasp_height_fraction=fraction)
                contexts[fraction] = baseline.prepare(scene, cfg)
            found = baseline.plan_angle(contexts[fraction], candidate.alpha + offset, index)
            if found.ok:
                out[(fraction, offset)] = found
    return out


def choose_height(scene: Scene, candidate: Candidate, config: Config, pool=None,
                  geometry: ArmGeometry | None = None) -> tuple[Candidate, dict]:
    """The candidate among `height_candidates` chosen by ``physics.height_choice`` and what was
    measured (per `start_key`, as text: its height h (m), its yaw offset (rad) and its press
    (m), with "clear" its side penetration (m) too, or its members' classes; the chosen key).
    "press": the first candidate (the start's first) whose path does not press on a box's top
    (`penetration.path_depths` at most ``press_tolerance``), else the start. "clear": the
    first that neither presses nor enters a non-target box's side deeper than
    ``side_tolerance``, else the first ranked by (presses, enters a side). "phi": the lowest
    mean `settled_class` over phi's ``ensemble.members`` members (inf where phi fails in any);
    ties to the earlier.
    ``geometry``: the scene's capsule arm with the boxes at rest (built here if None)."""
    found = height_candidates(scene, candidate, config)
    geometry = geometry or ArmGeometry(scene, "capsules")
    rule, physics = config.physics.height_choice, config.physics
    paths = {k: c.trajectory.q for k, c in found.items()}
    depths = box_depths(geometry, paths, config, scene.target) if rule != "phi" else {}
    record, scores = {}, {}
    for key, c in found.items():
        record[start_key(*key)] = entry = {"height": c.details.get("height"),
                                           "yaw_offset": key[1]}
        if rule == "phi":
            entry["classes"] = classes = _member_classes(scene, geometry, c, config, pool)
            scores[key] = (np.inf if None in classes else float(np.mean(classes)),)
            continue
        entry["press"] = depths[key][0]
        scores[key] = (float(entry["press"] > physics.press_tolerance),)
        if rule == "clear":
            entry["side"] = depths[key][1]
            scores[key] = (*scores[key], float(entry["side"] > physics.side_tolerance))
    chosen = min(found, key=lambda k: (*scores[k], list(found).index(k)))
    return found[chosen], {"rule": rule, "candidates": record, "chosen": start_key(*chosen)}


def box_depths(geometry: ArmGeometry, paths: dict, config: Config, target: str) -> dict:
    """Each knot path's (T + 1, 8) (press, side) depths (m; `penetration.path_depths` at
    ``physics.press_substeps`` configurations per interval, normals above
    ``physics.press_normal_z``; sides of every box but ``target``), the boxes where
    ``geometry`` last put them, by key."""
    return {k: path_depths(geometry, np.asarray(q, dtype=float), config.physics.press_substeps,
                           config.physics.press_normal_z, (target,))
            for k, q in paths.items()}


def _member_classes(scene: Scene, geometry: ArmGeometry, candidate: Candidate, config: Config,
                    pool=None) -> list[float | None]:
    """`settled_class` of the candidate's path in each of phi's ensemble members."""
    q = np.asarray(candidate.trajectory.q, dtype=float)
    knot_time = float(np.diff(candidate.trajectory.times[:2])[0])
    classes = []
    for member in range(config.ensemble.members):
        rollout = member_rollouts(scene, {"path": q}, config, member, pool, knot_time)["path"]
        classes.append(settled_class(scene, geometry, q[-1], rollout.final_boxes,
                                     config.evaluation))
    return classes
