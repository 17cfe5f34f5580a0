"""Choosing the grasp height at each approach angle in phi's ensemble (beyond the paper).

Sec. IV fixes the grasp height h (``baseline.grasp_height_fraction`` of the target's height) and
the physics planner starts from the baseline's path at that height. Which height succeeds
depends on the scene (the boxes beside the target that the fingers or the palm would land on,
the part of the target the pads close on), and no single height is better on average
(docs/physics_planner.md, 2026-11-26). The baseline cannot choose: it ignores the boxes. phi
sees them. With ``physics.grasp_heights`` the baseline is planned at each listed height too
(the same angle and IK seeds), every path is rolled out in each of phi's ensemble members (one
phi per path: their starts differ), and the judge's classes are read on phi's state after the
hold tail (`settled_class`, with the judge's own definitions from `scene.grading`), averaged
over the members as the robust judge averages its replays. The path with the best mean class
becomes the physics planner's start; ties go to the baseline's height, then to the listed order.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix

from drake_clutter.common.config import Config, EvaluationConfig
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.physics.ensemble import member_rollouts
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.scene.grading import off_the_board, target_zone_reason
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
    states = np.asarray([final[n][:7] if n in final else _rest_state(scene, n) for n in names])
    p = states[:, 4:7]
    quat = states[:, :4] / np.linalg.norm(states[:, :4], axis=1, keepdims=True)
    x, y = quat[:, 1], quat[:, 2]
    tilt = np.arccos(np.clip(1 - 2 * (x * x + y * y), -1, 1))  # angle of z_B from z_W
    fallen = off_the_board(scene, p)
    tipped = ~fallen & (tilt > evaluation.max_tilt)
    X_WG = geometry.tool_jacobian(q_last)[0]
    i = names.index(scene.target)
    R_WG = X_WG.rotation().matrix()
    R_WT = RotationMatrix(Quaternion(quat[i])).matrix()
    reason = target_zone_reason(R_WG.T @ (p[i] - X_WG.translation()), R_WG.T @ R_WT,
                                scene.target_box.size, float(q_last[7]), evaluation)
    others = [k for k, n in enumerate(names) if n != scene.target]
    grade = 2 if fallen.any() or reason else 1 if tipped[others].any() else 0
    return grade + 0.01 * int(fallen.sum() + tipped.sum())


def _rest_state(scene: Scene, name: str) -> np.ndarray:
    """A box's (quaternion wxyz, position in W) where the scene put it, resting on the board."""
    box = next(b for b in scene.boxes if b.name == name)
    x, y, yaw = box.pose
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2),
                     x, y, scene.shelf.top_height + box.size[2] / 2])


def height_candidates(scene: Scene, candidate: Candidate, config: Config
                      ) -> dict[float, Candidate]:
    """The start ``candidate`` (the baseline's, at ``baseline.grasp_height_fraction``) and the
    baseline planned at the same angle at each fraction of ``physics.grasp_heights``, by
    fraction (the start's first); only candidates with a trajectory ("ok")."""
    alphas = approach_angles(config.baseline)
    index = int(np.argmin(np.abs(alphas - candidate.alpha)))
    out = {config.baseline.grasp_height_fraction: candidate}
    for fraction in config.physics.grasp_heights:
        if fraction in out:
            continue
        cfg = replace(config.baseline, grasp_height_fraction=fraction)
        found = baseline.plan_angle(baseline.prepare(scene, cfg), candidate.alpha, index)
        if found.ok:
            out[fraction] = found
    return out


def choose_height(scene: Scene, candidate: Candidate, config: Config, pool=None
                  ) -> tuple[Candidate, dict]:
    """The candidate among `height_candidates` whose path has the lowest mean `settled_class`
    over phi's ``ensemble.members`` members (inf where phi fails in any), and what was
    measured: per fraction (as text) its height h (m) and members' classes, and the chosen
    fraction. Ties go to the earlier candidate (the start's first)."""
    found = height_candidates(scene, candidate, config)
    geometry = ArmGeometry(scene, "capsules")
    record, scores = {}, {}
    for fraction, c in found.items():
        q = np.asarray(c.trajectory.q, dtype=float)
        classes = []
        for member in range(config.ensemble.members):
            rollout = member_rollouts(scene, {"path": q}, config, member, pool,
                                      float(np.diff(c.trajectory.times[:2])[0]))["path"]
            classes.append(settled_class(scene, geometry, q[-1], rollout.final_boxes,
                                         config.evaluation))
        scores[fraction] = (np.inf if None in classes else float(np.mean(classes)))
        record[f"{fraction:g}"] = {"height": c.details.get("height"), "classes": classes}
    chosen = min(found, key=lambda f: (scores[f], list(found).index(f)))
    return found[chosen], {"candidates": record, "chosen": f"{chosen:g}"}
