"""The arm's planning geometry: signed distances between the arm and its obstacles, with
Jacobians, and the geometric checks of a path against the boxes at rest (shared by the planners).

A kinematic Drake planning world (`drake_world.build_planning_world`: the arm in one geometry
variant, the shelf, every scene box as a free body) answers two questions at a configuration of
the arm (TRAJECTORY_JOINTS: 7 angles in rad, the gripper opening in m) and poses X_WB of the
boxes (W):

* `ArmGeometry.contacts`: every arm-vs-obstacle pair (shelf part or box) closer than a distance,
  with the signed distance d (m) and its gradients: over the arm's 8 coordinates, and over the
  box's pose perturbation (dtheta, dp) (a rotation vector in W on the left, R' = exp([dtheta]x) R,
  and a translation in W: `state.StateLayout`'s tangent coordinates);
* `ArmGeometry.tool`: the tool frame's origin p_WG and z axis in W with their Jacobians over the
  arm's 8 coordinates.

The planning world filters every pair but arm-vs-obstacle, so box-box and box-shelf distances
are not available here.

`path_depths` (and `box_depths` over several paths) reads the deepest press on a box's top and
the deepest entry into a box's side along a path: the judge's usual kinematic failure, and side
contact, as geometric checks on the boxes where the geometry puts them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.tree import JacobianWrtVariable

from drake_clutter.common.config import Config
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import robot_positions
from drake_clutter.worlds.drake_world import World, box_rest_pose, build_planning_world

SHELF = "shelf"  # the obstacle name of every shelf part in `Contact.obstacle`
SWEEP_REACH = 0.15  # m, how far from its body origin an arm geometry reaches (the PR2 finger
# pads, the farthest, end ~0.11 m from the finger frame): `ArmGeometry.sweep`'s lever arm


@dataclass(frozen=True)
class Contact:
    """One arm-vs-obstacle pair: signed distance d (m), dd/dq over the arm's 8 coordinates,
    the obstacle (``SHELF`` or a box name), for a box dd/d(dtheta, dp) (6,), and the unit
    normal from the obstacle to the arm (W)."""

    distance: float
    d_dq: np.ndarray
    obstacle: str
    d_dbox: np.ndarray | None
    normal: np.ndarray


class ArmGeometry:
    """Arm-vs-obstacle distances and the tool frame in a planning world (module docstring)."""

    def __init__(self, scene: Scene, variant: str = "capsules", world: World | None = None):
        self.scene = scene
        self.world = world or build_planning_world(scene, variant)
        self.plant = self.world.plant
        self.root = self.world.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self.root)
        self._robot_q = self.world.robot_position_indices()
        inspector = self.world.scene_graph.model_inspector()
        self._robot_bodies = [self.plant.get_body(i)
                              for i in self.plant.GetBodyIndices(self.world.robot)]
        robot_frames = {self.plant.GetBodyFrameIdOrThrow(b.index()): b.index()
                        for b in self._robot_bodies}
        box_frames = {self.plant.GetBodyFrameIdOrThrow(self.world.box_body(n).index()): n
                      for n in self.world.box_names}
        self._robot_geometry, self._box_geometry = {}, {}
        for gid in inspector.GetAllGeometryIds():
            frame, X = inspector.GetFrameId(gid), inspector.GetPoseInFrame(gid)
            if frame in robot_frames:
                self._robot_geometry[gid] = (robot_frames[frame], X)
            elif frame in box_frames:
                self._box_geometry[gid] = (box_frames[frame], X)
        self._rest = {b.name: box_rest_pose(scene, b) for b in scene.boxes}
        self._poses = dict(self._rest)
        # d(robot positions)/d(trajectory coordinates): the fingers each move half the gap.
        self._dq_robot = np.zeros((9, 8))
        self._dq_robot[:7, :7] = np.eye(7)
        self._dq_robot[7:, 7] = 0.5

    def set_state(self, q: np.ndarray, box_poses: dict[str, RigidTransform] | None = None):
        """Puts the arm at ``q`` (8,) and the named boxes at their X_WB (others: where they were
        last put, at first their resting poses)."""
        if box_poses:
            self._poses.update(box_poses)
        positions = self.plant.GetPositions(self.context)
        positions[self._robot_q] = robot_positions(np.asarray(q, dtype=float))
        self.plant.SetPositions(self.context, positions)
        for name, X in self._poses.items():
            self.plant.SetFreeBodyPose(self.context, self.world.box_body(name), X)

    def rest_pose(self, name: str) -> RigidTransform:
        """X_WB of a scene box resting at its planar pose."""
        return self._rest[name]

    def contacts(self, q, box_poses=None, max_distance: float = 0.0,
                 obstacles: str = "all") -> list[Contact]:
        """Arm-vs-obstacle pairs closer than ``max_distance`` (m); ``obstacles`` is "all",
        "shelf" or "boxes". Pairs with a degenerate normal are skipped."""
        self.set_state(q, box_poses)
        query = self.plant.get_geometry_query_input_port().Eval(self.context)
        found = []
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(max_distance):
            if pair.id_A in self._robot_geometry:
                arm, other, p_arm, p_other, n = (pair.id_A, pair.id_B, pair.p_ACa, pair.p_BCb,
                                                 pair.nhat_BA_W)
            else:
                arm, other, p_arm, p_other, n = (pair.id_B, pair.id_A, pair.p_BCb, pair.p_ACa,
                                                 -pair.nhat_BA_W)
            n = np.asarray(n)
            box = self._box_geometry.get(other)
            if not np.all(np.isfinite(n)) or (obstacles == "shelf" and box is not None) or (
                    obstacles == "boxes" and box is None):
                continue
            found.append(self._contact(pair.distance, arm, p_arm, n, box, p_other))
        return found

    def _contact(self, distance, arm, p_arm, n, box, p_other) -> Contact:
        body, X_BG = self._robot_geometry[arm]
        J = self.plant.CalcJacobianTranslationalVelocity(
            self.context, JacobianWrtVariable.kQDot, self.plant.get_body(body).body_frame(),
            X_BG.multiply(p_arm), self.plant.world_frame(), self.plant.world_frame())
        d_dq = n @ J[:, self._robot_q] @ self._dq_robot
        if box is None:
            return Contact(float(distance), d_dq, SHELF, None, n)
        name, X_BoxG = box
        X_WB = self._poses[name]
        r = X_WB.rotation().multiply(X_BoxG.multiply(p_other))  # witness point from p_WB, in W
        return Contact(float(distance), d_dq, name, np.concatenate([-np.cross(r, n), -n]), n)

    def sweep(self, q_a, q_b, pieces: int = 4, reach: float = SWEEP_REACH) -> float:
        """A bound (m) on how far any arm point travels as the arm moves linearly in joint
        space from ``q_a`` to ``q_b`` (8,): the largest, over the arm's bodies, of the path
        length of the body origin plus ``reach`` times the angle the body turns, both summed
        over ``pieces`` equal chords of the segment (the boxes are not moved)."""
        bodies = self._robot_bodies
        poses = []
        for lam in np.linspace(0.0, 1.0, pieces + 1):
            self.set_state((1.0 - lam) * np.asarray(q_a) + lam * np.asarray(q_b))
            poses.append([self.plant.EvalBodyPoseInWorld(self.context, b) for b in bodies])
        longest = 0.0
        for j in range(len(bodies)):
            path = 0.0
            for before, after in zip(poses[:-1], poses[1:], strict=True):
                X = before[j].InvertAndCompose(after[j])
                path += (np.linalg.norm(X.translation())
                         + reach * abs(X.rotation().ToAngleAxis().angle()))
            longest = max(longest, path)
        return longest

    def tool(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(p_WG (3,), z axis of G in W (3,), dp_WG/dq (3, 8), dz/dq (3, 8)) at ``q`` (8,)."""
        X_WG, J = self._tool(q)
        z, dz = self._axis(X_WG, J, 2)
        return X_WG.translation(), z, J[3:], dz

    def tool_axis(self, q, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """(unit ``axis`` (0 = x, the approach) of G in W (3,), its derivative d/dq (3, 8))."""
        return self._axis(*self._tool(q), axis)

    def tool_jacobian(self, q) -> tuple[RigidTransform, np.ndarray]:
        """X_WG at ``q`` (8,) and G's spatial-velocity Jacobian [w; v] in W over the 8
        trajectory joints (6, 8)."""
        return self._tool(q)

    def _tool(self, q) -> tuple[RigidTransform, np.ndarray]:
        """X_WG and G's spatial-velocity Jacobian in W over the 8 trajectory joints (6, 8)."""
        self.set_state(q)
        frame, world = self.world.tool_frame, self.plant.world_frame()
        X_WG = frame.CalcPoseInWorld(self.context)
        J = self.plant.CalcJacobianSpatialVelocity(self.context, JacobianWrtVariable.kQDot,
                                                   frame, np.zeros(3), world, world)
        return X_WG, J[:, self._robot_q] @ self._dq_robot

    @staticmethod
    def _axis(X_WG: RigidTransform, J: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
        a = X_WG.rotation().matrix()[:, axis]
        return a, -_skew(a) @ J[:3]  # da = w x a


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def pressing(contacts: list[Contact], normal_z: float) -> list[Contact]:
    """The arm-box pairs of ``contacts`` whose normal from the box to the arm (W) has an up
    component above ``normal_z``: the arm above a box's top."""
    return [c for c in contacts if c.obstacle != SHELF and c.normal[2] > normal_z]


def path_press(geometry: ArmGeometry, q: np.ndarray, substeps: int, normal_z: float) -> float:
    """The deepest press over a path (m, 0 where none): the largest penetration of an
    arm-box pair that presses down (`pressing`) over ``substeps`` configurations per knot
    interval of ``q`` (knots, 8 each), the boxes where ``geometry`` last put them (at first
    their resting poses). The judge's usual kinematic failure as a geometric check."""
    return path_depths(geometry, q, substeps, normal_z)[0]


def path_depths(geometry: ArmGeometry, q: np.ndarray, substeps: int, normal_z: float,
                side_exclude: tuple[str, ...] = ()) -> tuple[float, float]:
    """(press, side) over a path (m, 0 where none): the deepest penetration of an arm-box pair
    that presses down (`pressing`, every box) and of one that does not (the arm against a
    box's side; boxes in ``side_exclude`` skipped), over ``substeps`` configurations per knot
    interval of ``q`` (knots, 8 each), the boxes where ``geometry`` last put them."""
    q = np.asarray(q, dtype=float)
    press = side = 0.0
    for q_a, q_b in zip(q[:-1], q[1:], strict=True):
        for lam in np.arange(1, substeps + 1) / substeps:
            found = geometry.contacts((1 - lam) * q_a + lam * q_b, None, 0.0, "boxes")
            down = {id(c) for c in pressing(found, normal_z)}
            for c in found:
                if id(c) in down:
                    press = max(press, -c.distance)
                elif c.obstacle not in side_exclude:
                    side = max(side, -c.distance)
    return press, side


def box_depths(geometry: ArmGeometry, paths: dict, config: Config, target: str) -> dict:
    """Each knot path's (T + 1, 8) (press, side) depths (m; `geometry.path_depths` at
    ``starts.press_substeps`` configurations per interval, normals above
    ``starts.press_normal_z``; sides of every box but ``target``), the boxes where
    ``geometry`` last put them, by key."""
    return {k: path_depths(geometry, np.asarray(q, dtype=float), config.starts.press_substeps,
                           config.starts.press_normal_z, (target,))
            for k, q in paths.items()}


def contact_flags(depths: dict, config: Config) -> dict:
    """Per key of ``depths`` (`box_depths`' (press, side) in m): (whether the path presses on a
    box's top deeper than ``starts.press_tolerance``, whether it enters a non-target box's side
    deeper than ``starts.side_tolerance``). A path with neither is clear of the boxes."""
    starts = config.starts
    return {k: (press > starts.press_tolerance, side > starts.side_tolerance)
            for k, (press, side) in depths.items()}


def clear_paths(geometry: ArmGeometry, paths: dict, config: Config, target: str) -> list:
    """The keys of ``paths`` (knot paths (T + 1, 8)), in order, whose path neither presses on
    a box's top deeper than ``starts.press_tolerance`` nor enters a non-target box's side
    deeper than ``starts.side_tolerance`` (`box_depths`, `contact_flags`)."""
    flags = contact_flags(box_depths(geometry, paths, config, target), config)
    return [key for key, found in flags.items() if not any(found)]


def pregrasp_aim(geometry: ArmGeometry, q_pregrasp: np.ndarray, target: str,
                 grasp_offset: float) -> np.ndarray:
    """c_grasp's aim in the target's frame T (m): the gripper point (``grasp_offset`` m behind
    G along x_G, `approach.grasp_offset`) at the pre-grasp configuration ``q_pregrasp`` (8,),
    the target at rest where ``geometry`` has it."""
    p, _, _, _ = geometry.tool(q_pregrasp)
    if grasp_offset:
        p = p - grasp_offset * geometry.tool_axis(q_pregrasp, 0)[0]
    return geometry.rest_pose(target).inverse().multiply(np.asarray(p, dtype=float))
