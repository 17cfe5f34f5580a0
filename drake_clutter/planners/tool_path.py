"""The tool frame G along a path, shared by the planners that bend or build paths (beyond the
paper): the approach frame of a straight path (`approach_frame`), and joint configurations that
put G on Cartesian targets (`follow_targets`: each knot from its own seed; `follow_chain`: each
knot from the one before). Frames: W the world, G the tool frame; metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_clutter.planners.geometry import ArmGeometry

ARM = 7  # arm joints; column 7 of a path is the gripper opening (m)
UP = np.array([0.0, 0.0, 1.0])
DAMPING = 1e-6  # damped least squares: lambda^2 added to J J^T (m^2, rad^2)
POSE_TOLERANCE = 1e-4  # m and rad: a knot's G is on its target within this
MAX_NEWTON = 20  # Gauss-Newton steps per knot at most


@dataclass(frozen=True)
class ApproachFrame:
    """G's positions along the straight path (T + 1, 3, W), the approach direction ``d`` and
    ``side`` (unit, horizontal, W), and each knot's depth along d from the pre-grasp (m)."""

    positions: np.ndarray
    d: np.ndarray
    side: np.ndarray

    @property
    def along(self) -> np.ndarray:
        """Each knot's G depth along d relative to the pre-grasp (m, <= 0 before it)."""
        return (self.positions - self.positions[-1]) @ self.d

    def progress_at(self, depth: float) -> float:
        """The straight path's progress (0..1) where G first reaches ``depth`` (m along d from
        the pre-grasp), clipped to the path."""
        reached = np.maximum.accumulate(self.along)
        s = np.linspace(0.0, 1.0, len(reached))
        keep = np.r_[True, np.diff(reached) > 1e-9]
        return float(np.interp(depth, reached[keep], s[keep]))


def approach_frame(geometry: ArmGeometry, straight: np.ndarray) -> ApproachFrame:
    """The approach frame of the straight path (T + 1, 8) (module docstring)."""
    positions = np.array([geometry.tool_jacobian(q)[0].translation() for q in straight])
    d = geometry.tool_axis(straight[-1], 0)[0].copy()
    d[2] = 0.0
    d /= np.linalg.norm(d)
    side = np.cross(UP, d)
    return ApproachFrame(positions, d, side / np.linalg.norm(side))


def rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation vector (W) that turns R onto R_target (small angles)."""
    E = R_target @ R.T
    return 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])



def follow_targets(geometry: ArmGeometry, seeds: np.ndarray, targets: np.ndarray,
                   rotations: np.ndarray) -> tuple[np.ndarray, float]:
    """Arm configurations (K, 8) that put G at ``targets`` (K, 3, W) with ``rotations`` (K, 3,
    3), each found by damped Gauss-Newton from its seed row (K, 8; the opening is kept), and
    the largest remaining pose error (m or rad)."""
    out = np.array(seeds, dtype=float)
    worst = 0.0
    for k in range(len(out)):
        for _ in range(MAX_NEWTON):
            X, J = geometry.tool_jacobian(out[k])
            err = np.r_[rotation_error(rotations[k], X.rotation().matrix()),
                        targets[k] - X.translation()]
            if np.abs(err).max() < POSE_TOLERANCE:
                break
            Ja = J[:, :ARM]
            out[k, :ARM] += Ja.T @ np.linalg.solve(Ja @ Ja.T + DAMPING * np.eye(6), err)
        X, _ = geometry.tool_jacobian(out[k])
        err = np.r_[rotation_error(rotations[k], X.rotation().matrix()),
                    targets[k] - X.translation()]
        worst = max(worst, float(np.abs(err).max()))
    return out, worst


def follow_chain(geometry: ArmGeometry, seed: np.ndarray, targets: np.ndarray,
                 rotation: np.ndarray, opening: np.ndarray) -> tuple[np.ndarray, float]:
    """Arm configurations (K, 8) that put G at ``targets`` (K, 3, W) with the one ``rotation``
    (3, 3) or each knot's (K, 3, 3), knot k solved from knot k - 1's answer (knot 0 from
    ``seed`` (8,)), so that the arm moves continuously; column 7 is ``opening`` (K,) (m). Also
    the largest remaining pose error (m or rad)."""
    out = np.empty((len(targets), len(seed)))
    rotations = np.broadcast_to(rotation, (len(targets), 3, 3))
    worst, previous = 0.0, np.asarray(seed, float)
    for k in range(len(targets)):
        row = previous.copy()
        row[ARM] = opening[k]
        solved, error = follow_targets(geometry, row[None], targets[k:k + 1],
                                       rotations[k:k + 1])
        out[k], previous = solved[0], solved[0]
        worst = max(worst, error)
    return out, worst
