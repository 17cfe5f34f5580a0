"""The geometry of Sec. III's classes on a state of the scene: a box tilted or off the board,
the target in the gripper's pre-grasp zone, another box reaching into it (`box_overlap`); and
the classes themselves (`OutcomeKind`, `classify`'s precedence, `behaviour_grade`).

The judge reads them on Bullet's state at the end of a replay (`evaluation.judge`); the physics
planner reads the same definitions on phi's state to choose among its paths without the judge
(`planners.physics.grasp_height`). Frames: W the world, G the tool frame; metres, radians.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import StrEnum

import numpy as np

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import Scene


def tilt_angle(R_WB: np.ndarray) -> np.ndarray:
    """Angle(s) (rad) between a box's z axis and W's z axis, R_WB of shape (..., 3, 3)."""
    return np.arccos(np.clip(np.asarray(R_WB)[..., 2, 2], -1.0, 1.0))


def off_the_board(scene: Scene, p_WB: np.ndarray) -> np.ndarray:
    """True where a box centre (rows of p_WB, W) is outside the board's footprint or below its
    top surface (Sec. III: "falls over the edge of the working surface")."""
    p = np.atleast_2d(p_WB)
    return (edge_distance(scene, p) < 0.0) | (p[:, 2] < scene.shelf.top_height)


def zone_extent(opening: float, config: EvaluationConfig) -> tuple[np.ndarray, np.ndarray]:
    """The pre-grasp zone as an axis-aligned box in the tool frame G: (centre, half extents), m.

    Between the pads' inner faces (|y| < opening / 2), along the pads' length (x) extended by
    ``zone_margin`` at both ends, and over the pads' height (z).
    """
    pad_x0 = pr2.PAD_CENTER_X - pr2.PAD_SIZE[0] / 2 - pr2.TOOL_OFFSET
    pad_x1 = pad_x0 + pr2.PAD_SIZE[0]
    x0, x1 = pad_x0 - config.zone_margin, pad_x1 + config.zone_margin
    centre = np.array([(x0 + x1) / 2, 0.0, 0.0])
    half = np.array([(x1 - x0) / 2, max(opening, 0.0) / 2, pr2.PAD_SIZE[2] / 2])
    return centre, half


def target_zone_reason(p_GT, R_GT, size, opening: float, config: EvaluationConfig) -> str:
    """"" when a target box (centre p_GT, rotation R_GT in G, full size in m) sits in the
    pre-grasp zone of a gripper open by ``opening`` m, else why not.

    In the zone: its centre lies within the zone's x range; its extent across the gripper
    (along y_G) fits between the pads (``fit_tolerance``); the pads' height lies within its
    extent along z_G (so they would close on its sides, not above or below it).
    """
    p = np.asarray(p_GT, dtype=float)
    reach = np.abs(np.asarray(R_GT)) @ (np.asarray(size, dtype=float) / 2)  # half extents in G
    centre, half = zone_extent(opening, config)
    tol = config.fit_tolerance
    if abs(p[0] - centre[0]) > half[0]:
        where = "ahead of" if p[0] > centre[0] else "behind"
        return f"target centre {abs(p[0] - centre[0]) - half[0]:.3f} m {where} the pad zone"
    if abs(p[1]) + reach[1] > opening / 2 + tol:
        return (f"target does not fit between the pads (needs {abs(p[1]) + reach[1]:.3f} m "
                f"of the {opening / 2:.3f} m half gap)")
    if abs(p[2]) + half[2] > reach[2] + tol:
        return f"pads not level with the target (height offset {p[2]:.3f} m)"
    return ""


def target_zone_ratio(p_GT, R_GT, size, opening: float, config: EvaluationConfig) -> float:
    """How far a target box (as `target_zone_reason` takes it) sits from the pre-grasp zone,
    unitless: the largest of its three tests' ratios (the centre's offset along x_G over the
    zone's half length; the extent across the gripper over the half gap plus
    ``fit_tolerance``; the pads' half height and offset along z_G over the target's half extent
    plus ``fit_tolerance``). Above 1 exactly where `target_zone_reason` names a reason."""
    p = np.asarray(p_GT, dtype=float)
    reach = np.abs(np.asarray(R_GT)) @ (np.asarray(size, dtype=float) / 2)
    centre, half = zone_extent(opening, config)
    tol = config.fit_tolerance
    return float(max(abs(p[0] - centre[0]) / half[0],
                     (abs(p[1]) + reach[1]) / (opening / 2 + tol),
                     (abs(p[2]) + half[2]) / (reach[2] + tol)))


def edge_distance(scene: Scene, p_WB: np.ndarray) -> np.ndarray:
    """Each box centre's (rows of p_WB, W) distance inside the board's footprint (m; negative
    outside it): the margin `off_the_board` tests horizontally."""
    shelf = scene.shelf
    p = np.atleast_2d(p_WB)
    cx, cy = shelf.center_xy
    return np.minimum(shelf.depth / 2 - np.abs(p[:, 0] - cx),
                      shelf.width / 2 - np.abs(p[:, 1] - cy))


def box_overlap(p_a, R_a, half_a, p_b, R_b, half_b) -> float:
    """How deep (m, >= 0) two boxes overlap (centres p and rotations R in one frame, half
    extents in m): the smallest overlap of their projections over the 15 separating axes (the
    six faces' normals and the nine edge pairs' crosses), the translation that parts them; 0
    where an axis separates them."""
    R_a, R_b = np.asarray(R_a, dtype=float), np.asarray(R_b, dtype=float)
    axes = [R_a[:, i] for i in range(3)] + [R_b[:, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            c = np.cross(R_a[:, i], R_b[:, j])
            if np.linalg.norm(c) > 1e-9:
                axes.append(c / np.linalg.norm(c))
    d = np.asarray(p_b, dtype=float) - np.asarray(p_a, dtype=float)
    depth = np.inf
    for n in axes:
        reach = (np.abs(R_a.T @ n) @ np.asarray(half_a, dtype=float)
                 + np.abs(R_b.T @ n) @ np.asarray(half_b, dtype=float))
        depth = min(depth, reach - abs(float(d @ n)))
        if depth <= 0.0:
            return 0.0
    return float(depth)


# ----------------------------------------------------------------------------- classes


class OutcomeKind(StrEnum):
    """Sec. III's outcome classes of a replayed plan, best first (the value is what outcome
    files and stores hold); ``planner_failure``: the planner gave no trajectory."""

    SUCCESS = "success"
    PARTIAL_SUCCESS = "partial_success"
    FAILURE_TO_GRASP = "failure_to_grasp"
    OBJECTS_FALLING = "objects_falling"
    KINEMATIC_FAILURE = "kinematic_failure"
    PLANNER_FAILURE = "planner_failure"


OUTCOME_KINDS: tuple[str, ...] = tuple(k.value for k in OutcomeKind)


def classify(kinematic_failure: str, fallen: Sequence[str], grasp_reason: str,
             tipped: Sequence[str]) -> tuple[OutcomeKind, str]:
    """(kind, reason) from the findings, with the documented precedence.

    ``kinematic_failure``: its reason or ""; ``fallen``/``tipped``: box names; ``grasp_reason``:
    "" when the target is grasped, else why not.
    """
    if kinematic_failure:
        return OutcomeKind.KINEMATIC_FAILURE, kinematic_failure
    if fallen:
        return OutcomeKind.OBJECTS_FALLING, "fell off the shelf: " + ", ".join(fallen)
    if grasp_reason:
        return OutcomeKind.FAILURE_TO_GRASP, grasp_reason
    if tipped:
        return OutcomeKind.PARTIAL_SUCCESS, "grasped; tipped over: " + ", ".join(tipped)
    return OutcomeKind.SUCCESS, "grasped; every obstacle upright on the shelf"


# Sec. VI-A's comparison of two plans from the same angle: the class, then the boxes disturbed.
GRADE_CLASSES = {"success": 0, "partial_success": 1, "failure_to_grasp": 2, "objects_falling": 2,
                 "kinematic_failure": 3, "planner_failure": 4}


def behaviour_grade(kind: str, disturbed: int) -> tuple[int, int]:
    """(class, disturbed boxes) of one plan's outcome; lower is better. Class 0 success, 1
    partial success, 2 failure to grasp or objects falling, 3 kinematic failure, 4 no plan;
    disturbed = boxes tipped or fallen. A kinematic failure stops the replay where it is found,
    so its count of disturbed boxes is not comparable with a whole replay's: it ranks below."""
    if kind not in GRADE_CLASSES:
        raise ValueError(f"unknown outcome kind {kind!r}")
    return GRADE_CLASSES[kind], int(disturbed)
