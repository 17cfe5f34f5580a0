"""phi's state, tangent and control coordinates (Sec. V), and the boxes' 13-number states.

State x (numbers, shape (nx,), nx = 8 + 13 n): the arm's configuration (TRAJECTORY_JOINTS
order: 7 arm angles in rad, the gripper opening in m), then per box of
``StateLayout.box_names`` its quaternion (w, x, y, z) of R_WB, position p_WB (m), angular
velocity w_WB (rad/s) and translational velocity v_WB (m/s), all in W: Drake's floating-body
q and v. Tangent coordinates dx (shape (ndx,), ndx = 8 + 12 n): the arm's 8, then per box
(dtheta, dp, dw, dv), dtheta a rotation vector in W: R' = exp([dtheta]x) R.
`StateLayout.retract` / `StateLayout.difference` map between the two. Control u (shape (8,)):
the arm's configuration at the end of a knot interval. `dynamics` steps these states.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial.transform import Rotation

from drake_clutter.scene.scenes import Scene
from drake_clutter.worlds.drake_world import box_rest_pose

ARM_DIM = 8  # TRAJECTORY_JOINTS: 7 arm joints + gripper opening
NU = 8  # controls: the arm's next configuration (TRAJECTORY_JOINTS)
BOX_DIM = 13  # quaternion wxyz, p_WB, w_WB, v_WB
BOX_TANGENT = 12  # dtheta, dp, dw, dv


# ----------------------------------------------------------------------------- rotations


def _quat_wxyz_to_rotation(q: np.ndarray) -> Rotation:
    """Rotations of quaternion rows; a non-finite or zero row becomes the identity (callers
    turn its result into NaN with `_bad_rows`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))[:, [1, 2, 3, 0]].copy()
    q[_bad_rows(q)] = [0.0, 0.0, 0.0, 1.0]
    return Rotation.from_quat(q)


def _bad_rows(v: np.ndarray) -> np.ndarray:
    """Rows of a 2-D array that are not finite, or all zero."""
    v = np.atleast_2d(v)
    return ~np.all(np.isfinite(v), axis=1) | ~np.any(v != 0.0, axis=1)


def _rotation_to_quat_wxyz(r: Rotation) -> np.ndarray:
    q = np.atleast_2d(r.as_quat())[:, [3, 0, 1, 2]]
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)  # w >= 0: one representative


def quaternion_tangent_basis(q: np.ndarray) -> np.ndarray:
    """E(q) (4x3): dq = E(q) dtheta for R' = exp([dtheta]x) R(q), q = (w, x, y, z) unit."""
    w, x, y, z = q
    # 0.5 * [0, dtheta] (x) q, written as a matrix acting on dtheta.
    return 0.5 * np.array([[-x, -y, -z],
                           [w, z, -y],
                           [-z, w, x],
                           [y, -x, w]])


# ----------------------------------------------------------------------------- layout


@dataclass(frozen=True)
class StateLayout:
    """Where everything sits in x and dx (see the module docstring)."""

    box_names: tuple[str, ...]

    @property
    def num_boxes(self) -> int:
        """Boxes in the state (the kept ones)."""
        return len(self.box_names)

    @property
    def nx(self) -> int:
        """Length of x."""
        return ARM_DIM + BOX_DIM * self.num_boxes

    @property
    def ndx(self) -> int:
        """Length of a tangent vector dx."""
        return ARM_DIM + BOX_TANGENT * self.num_boxes

    @property
    def nu(self) -> int:
        """Length of u."""
        return NU

    def boxes(self, x: np.ndarray) -> np.ndarray:
        """Box states, shape (n, 13)."""
        return np.asarray(x)[ARM_DIM:].reshape(self.num_boxes, BOX_DIM)

    def is_state(self, x: np.ndarray) -> bool:
        """Whether x is a state phi can go on from: finite, every box quaternion of unit norm
        within 1e-6 (SAP overflowing on a wild control breaks it)."""
        quats = self.boxes(x)[:, :4]
        return bool(np.all(np.isfinite(x))
                    and np.all(np.abs(np.linalg.norm(quats, axis=1) - 1) <= 1e-6))

    def box_index(self, name: str) -> int:
        """Index of a kept box in the state (ValueError if it is not kept)."""
        return self.box_names.index(name)

    def box_pose(self, x: np.ndarray, name: str) -> RigidTransform:
        """X_WB of a kept box in state x."""
        b = self.boxes(x)[self.box_index(name)]
        return RigidTransform(Quaternion(b[:4] / np.linalg.norm(b[:4])), b[4:7])

    def join(self, arm: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """x from the arm's 8 numbers and the (n, 13) box states."""
        return np.concatenate([np.asarray(arm, dtype=float),
                               np.asarray(boxes, dtype=float).reshape(-1)])

    def tangent_box_slice(self, i: int) -> slice:
        """Columns/rows of box i in tangent coordinates."""
        start = ARM_DIM + BOX_TANGENT * i
        return slice(start, start + BOX_TANGENT)

    def retract(self, x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """x (+) dx: rotations by exp([dtheta]x) on the left, everything else added."""
        boxes, d = self.boxes(x).copy(), np.asarray(dx)[ARM_DIM:].reshape(-1, BOX_TANGENT)
        if self.num_boxes:
            bad = _bad_rows(boxes[:, :4]) | ~np.all(np.isfinite(d[:, :3]), axis=1)
            turn = np.where(bad[:, None], 0.0, d[:, :3])
            rot = Rotation.from_rotvec(turn) * _quat_wxyz_to_rotation(boxes[:, :4])
            boxes[:, :4] = _rotation_to_quat_wxyz(rot)
            boxes[bad, :4] = np.nan  # a failed state stays failed, never an exception
            boxes[:, 4:] += d[:, 3:]
        return self.join(np.asarray(x)[:ARM_DIM] + np.asarray(dx)[:ARM_DIM], boxes)

    def difference(self, x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
        """x_a (-) x_b: the dx with retract(x_b, dx) = x_a (rotation vectors in W)."""
        a, b = self.boxes(x_a), self.boxes(x_b)
        d = np.zeros((self.num_boxes, BOX_TANGENT))
        if self.num_boxes:
            rel = _quat_wxyz_to_rotation(a[:, :4]) * _quat_wxyz_to_rotation(b[:, :4]).inv()
            d[:, :3] = rel.as_rotvec()
            d[_bad_rows(a[:, :4]) | _bad_rows(b[:, :4]), :3] = np.nan
            d[:, 3:] = a[:, 4:] - b[:, 4:]
        arm = np.asarray(x_a)[:ARM_DIM] - np.asarray(x_b)[:ARM_DIM]
        return np.concatenate([arm, d.reshape(-1)])

    def tangent_to_state(self, x: np.ndarray) -> np.ndarray:
        """G(x) (nx x ndx): dx -> first-order change of x (quaternion rows by E(q))."""
        G = np.zeros((self.nx, self.ndx))
        G[:ARM_DIM, :ARM_DIM] = np.eye(ARM_DIM)
        for i, b in enumerate(self.boxes(x)):
            r, c = ARM_DIM + BOX_DIM * i, ARM_DIM + BOX_TANGENT * i
            G[r:r + 4, c:c + 3] = quaternion_tangent_basis(b[:4] / np.linalg.norm(b[:4]))
            G[r + 4:r + BOX_DIM, c + 3:c + BOX_TANGENT] = np.eye(9)
        return G

    def state_to_tangent(self, x: np.ndarray) -> np.ndarray:
        """G+(x) (ndx x nx), the left inverse of G(x): E(q)^T E(q) = I/4, so E+ = 4 E^T; a
        change along q itself (the quaternion's norm) maps to zero."""
        P = self.tangent_to_state(x).T.copy()
        for i in range(self.num_boxes):
            c, r = ARM_DIM + BOX_TANGENT * i, ARM_DIM + BOX_DIM * i
            P[c:c + 3, r:r + 4] *= 4.0
        return P


def rest_box_state(scene: Scene, name: str) -> np.ndarray:
    """The 13-number state of a scene box resting at its planar pose, at rest."""
    return pose_to_box_state(box_rest_pose(scene, scene.box(name)))


def pose_to_box_state(X_WB: RigidTransform, V_WB: np.ndarray | None = None) -> np.ndarray:
    """13-number box state from a pose and an optional spatial velocity [w_WB, v_WB] (W)."""
    q = X_WB.rotation().ToQuaternion().wxyz()
    q = q if q[0] >= 0 else -q
    v = np.zeros(6) if V_WB is None else np.asarray(V_WB, dtype=float)
    return np.concatenate([q, X_WB.translation(), v])


def box_state_to_pose(b: np.ndarray) -> RigidTransform:
    """X_WB of a 13-number box state."""
    return RigidTransform(RotationMatrix(Quaternion(b[:4] / np.linalg.norm(b[:4]))), b[4:7])


def scene_box_states(scene: Scene) -> dict[str, np.ndarray]:
    """Every scene box at rest at its planar pose (name -> 13-number state)."""
    return {b.name: rest_box_state(scene, b.name) for b in scene.boxes}
