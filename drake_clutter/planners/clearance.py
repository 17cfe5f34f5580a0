"""Arm-vs-shelf clearance in a static planning world: signed distances with their gradients,
Table I's penetration, the sub-sampled static-hull cost of a joint path, and the dense check.

The static planning world (`approach.static_planning_world`) holds the arm and the shelf only,
so every pair SceneGraph reports is an arm geometry against a shelf part. A path is a (T, 7)
array of arm angles (rad) at knots, linear in joint space between knots; the gripper is held
fully open. c_static_hull^t approximates the penetration of the convex hull of each link's
poses at knots t-1 and t (Table I) by the mean, over ``substeps`` configurations evenly spaced
on the joint-space segment (t-1, t], of the sum over (arm geometry, shelf part) pairs of
Table I's penetration: 0 at d_safe apart, linear in depth once the shapes touch, quadratic in
between (`smooth_penetration`), which makes the cost C1 for SNOPT. Gradients come from the
plant's translational Jacobians at the witness points: d(distance)/dq = n^T J, n the unit
normal that moves the arm's point away from the shelf. Distances in m.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable

from drake_clutter.common.config import BaselineConfig
from drake_clutter.robot import pr2
from drake_clutter.worlds.drake_world import World

ARM_DOF = len(pr2.ARM_JOINTS)
OPENING = pr2.GRIPPER_MAX_OPENING  # m: the gripper stays fully open (Sec. V: c_grp_open)


# ----------------------------------------------------------------------------- distances


@dataclass(frozen=True)
class Contact:
    """One arm-vs-shelf pair: signed distance (m), the arm's witness point in its body frame,
    the unit normal in W along which moving that point increases the distance, and names."""

    distance: float
    body_index: object
    p_BC: np.ndarray
    n_W: np.ndarray
    arm_geometry: str
    shelf_geometry: str


class ShelfClearance:
    """Arm-vs-shelf signed distances in a static planning world, and the penetration cost.

    The world must have no boxes (`approach.static_planning_world`): its plant positions are
    the 7 arm joints then the 2 finger slides. The gripper is held fully open.
    """

    def __init__(self, world: World):
        index = world.robot_position_indices()
        if world.plant.num_positions() != len(index) or list(index) != list(range(len(index))):
            raise ValueError("ShelfClearance needs a world whose positions are the robot's only")
        self.world, self.plant = world, world.plant
        self.root = world.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self.root)
        self.fingers = world.robot_q(np.zeros(ARM_DOF), OPENING)[ARM_DOF:]
        inspector = world.scene_graph.model_inspector()
        robot_frames = {self.plant.GetBodyFrameIdOrThrow(i): i
                        for i in self.plant.GetBodyIndices(world.robot)}
        self._robot_geometry = {}  # geometry id -> (body index, X_BG)
        for gid in inspector.GetAllGeometryIds():
            body = robot_frames.get(inspector.GetFrameId(gid))
            if body is not None:
                self._robot_geometry[gid] = (body, inspector.GetPoseInFrame(gid))
        self._names = {gid: inspector.GetName(gid) for gid in inspector.GetAllGeometryIds()}

    def set_arm(self, q_arm) -> None:
        """Puts the arm at ``q_arm`` (7 angles, rad) with the gripper open."""
        self.plant.SetPositions(self.context, np.concatenate([q_arm, self.fingers]))

    def contacts(self, q_arm, max_distance: float) -> list[Contact]:
        """Every arm-vs-shelf pair closer than ``max_distance`` (m) at ``q_arm``."""
        self.set_arm(q_arm)
        query = self.plant.get_geometry_query_input_port().Eval(self.context)
        found = []
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(max_distance):
            if pair.id_A in self._robot_geometry:
                arm, shelf, p_GC, n = pair.id_A, pair.id_B, pair.p_ACa, pair.nhat_BA_W
            else:
                arm, shelf, p_GC, n = pair.id_B, pair.id_A, pair.p_BCb, -pair.nhat_BA_W
            body, X_BG = self._robot_geometry[arm]
            found.append(Contact(pair.distance, body, X_BG.multiply(p_GC), np.asarray(n),
                                 self._names[arm], self._names[shelf]))
        return found

    def penetration(self, q_arm, d_safe: float) -> tuple[float, np.ndarray]:
        """sum over pairs of `smooth_penetration` (m) at ``q_arm``, and its gradient (7,)."""
        value, grad = 0.0, np.zeros(ARM_DOF)
        for contact in self.contacts(q_arm, d_safe):
            if not np.all(np.isfinite(contact.n_W)):
                continue  # a degenerate normal (exact touching of some shapes): no direction
            v, slope = smooth_penetration(d_safe - contact.distance, d_safe)
            value += v
            J = self.plant.CalcJacobianTranslationalVelocity(
                self.context, JacobianWrtVariable.kQDot,
                self.plant.get_body(contact.body_index).body_frame(), contact.p_BC,
                self.plant.world_frame(), self.plant.world_frame())
            grad -= slope * (contact.n_W @ J[:, :ARM_DOF])
        return value, grad

    def deepest(self, q_arm) -> tuple[float, str]:
        """Penetration depth (m, >= 0; 0 when nothing touches) at ``q_arm`` and the pair's name."""
        worst, name = 0.0, ""
        for contact in self.contacts(q_arm, 0.0):
            if -contact.distance > worst:
                worst, name = -contact.distance, f"{contact.arm_geometry}/{contact.shelf_geometry}"
        return worst, name


def smooth_penetration(gap: float, d_safe: float) -> tuple[float, float]:
    """Table I's penetration, made C1: ``gap`` = d_safe - signed distance (m) > 0. Linear,
    ``gap - d_safe / 2``, once the shapes touch (gap >= d_safe); quadratic inside the margin,
    ``gap^2 / (2 d_safe)``, so value and slope are continuous. Returns (value, d value/d gap).
    """
    if gap >= d_safe:
        return gap - 0.5 * d_safe, 1.0
    return 0.5 * gap * gap / d_safe, gap / d_safe


def segment_samples(num_knots: int, substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-samples of the joint-space segments between knots: (interval, fraction) pairs.

    For each interval i (knots i and i+1, 0-based) the fractions k/substeps, k = 1..substeps,
    so every sample lies in (knot i, knot i+1] and the first knot is never sampled.
    """
    fractions = np.arange(1, substeps + 1) / substeps
    intervals = np.repeat(np.arange(num_knots - 1), substeps)
    return intervals, np.tile(fractions, num_knots - 1)


def static_hull_cost(clearance: ShelfClearance, q: np.ndarray, d_safe: float,
                     substeps: int) -> tuple[float, np.ndarray]:
    """sum_t c_static_hull^t of a path ``q`` (T, 7) and its gradient (T, 7) (see module doc)."""
    intervals, fractions = segment_samples(len(q), substeps)
    value, grad = 0.0, np.zeros_like(q)
    for i, lam in zip(intervals, fractions, strict=True):
        v, g = clearance.penetration((1.0 - lam) * q[i] + lam * q[i + 1], d_safe)
        if v > 0.0:
            value += v / substeps
            grad[i] += (1.0 - lam) * g / substeps
            grad[i + 1] += lam * g / substeps
    return value, grad


def velocity_cost(q: np.ndarray) -> float:
    """sum_t ||q^t - q^(t-1)||^2 of a path (T, n) (Table I's c_vel)."""
    return float(np.sum(np.diff(q, axis=0) ** 2))


# ----------------------------------------------------------------------------- dense check


@dataclass
class CheckResult:
    """Dense check of a path: passed, the deepest penetration (m), the pair, when (s), how
    many configurations were checked, and how long the check took (s)."""

    passed: bool
    depth: float
    where: str
    time: float
    samples: int
    seconds: float = 0.0


def dense_check(clearance: ShelfClearance, q: np.ndarray, config: BaselineConfig) -> CheckResult:
    """Checks ``check_substeps`` configurations per knot interval (and the first knot) of path
    ``q`` (T, 7): passes when no arm proxy penetrates the shelf by more than check_tolerance."""
    tic = time.perf_counter()
    intervals, fractions = segment_samples(len(q), config.check_substeps)
    samples = [(0, 0.0)] + list(zip(intervals, fractions, strict=True))
    depth, where, when = 0.0, "", 0.0
    for i, lam in samples:
        d, name = clearance.deepest((1.0 - lam) * q[i] + lam * q[i + 1] if lam else q[i])
        if d > depth:
            depth, where, when = d, name, (i + lam) * config.knot_time
    return CheckResult(depth <= config.check_tolerance, depth, where, when, len(samples),
                       time.perf_counter() - tic)
