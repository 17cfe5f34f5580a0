"""Approach angles, the gripper's start and pre-grasp poses, and their inverse kinematics (Sec. IV).

Notation (Drake monogram, see `world`): ``X_WG`` is the pose of the gripper's tool frame G in
the world frame W; metres and radians. An approach angle ``alpha`` is a rotation about +z of W:
the gripper moves along ``d(alpha) = (cos alpha, sin alpha, 0)``, so ``alpha = 0`` goes straight
into the shelf along +x and ``alpha > 0`` comes from the right (-y side) heading left.

Sec. IV: the gripper is horizontal at a fixed height ``h`` above the board; it starts on a line
``l`` outside the shelf and ends in the pre-grasp pose, the target centred between the open
fingers. Here the pre-grasp pose puts the pads' centre (``BaselineConfig.grasp_point``; G lies
1.5 cm ahead of it) at the target's centre (x, y), G at height ``board_top + h``, with G's
x-axis along ``d(alpha)`` and its z-axis up (fingers across, y).
The start pose has the same orientation, on the ray from the target back along ``-d(alpha)``,
where it crosses the line ``l``: ``x = front_x - (gripper reach ahead of G) - clearance``.

The planning world here is the scene's static part only (robot + shelf, no boxes): the baseline
ignores the movable boxes (Sec. IV), the target included.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Capsule, Role, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import IpoptSolver, SnoptSolver, SolverOptions

from drake_clutter.common.config import BaselineConfig
from drake_clutter.robot import pr2
from drake_clutter.robot.pr2 import ARM_DOF
from drake_clutter.scene.scenes import Scene
from drake_clutter.worlds.drake_world import World, build_planning_world

CONTINUOUS_JOINTS = tuple(i for i, name in enumerate(pr2.ARM_JOINTS)
                          if np.isinf(pr2.arm_joint_limits()[name][0]))
# Links rigidly attached to the tool frame: their proxies set the grasp height and line l.
_GRIPPER_LINKS = (pr2.PALM_LINK, *pr2.FINGER_LINKS,
                  pr2.ARM_JOINTS[-1].replace("_joint", "_link"))


@contextlib.contextmanager
def quiet_drake_warnings():
    """Silences drake's warnings (e.g. IPOPT's "iteration limit") inside the block: a failed
    attempt is an outcome the planner records, not something to print."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def static_planning_world(scene: Scene, variant: str = "capsules") -> World:
    """The planning world of ``scene`` without its boxes: arm (torso welded) and shelf only.

    The boxes, target included, are neither obstacles nor bodies here (the baseline ignores
    them, Sec. IV), so the plant's positions are exactly the 9 robot positions.
    """
    return build_planning_world(dataclasses.replace(scene, boxes=()), variant)


def approach_angles(config: BaselineConfig) -> np.ndarray:
    """``num_angles`` evenly spread angles (rad) strictly inside (alpha_min, alpha_max).

    The midpoints of ``num_angles`` equal sub-intervals: deterministic, symmetric, and never
    the open interval's end points.
    """
    if config.num_angles < 1 or not config.alpha_min < config.alpha_max:
        raise ValueError("need num_angles >= 1 and alpha_min < alpha_max")
    step = (config.alpha_max - config.alpha_min) / config.num_angles
    return config.alpha_min + step * (np.arange(config.num_angles) + 0.5)


def approach_direction(alpha: float) -> np.ndarray:
    """Unit vector d(alpha) in W (horizontal) along which the gripper approaches."""
    return np.array([np.cos(alpha), np.sin(alpha), 0.0])


def gripper_rotation(alpha: float) -> RotationMatrix:
    """R_WG of the horizontal gripper approaching along d(alpha): x = d, z = up, y = z x d."""
    d = approach_direction(alpha)
    z = np.array([0.0, 0.0, 1.0])
    return RotationMatrix(np.column_stack([d, np.cross(z, d), z]))


@dataclass(frozen=True)
class GripperExtent:
    """How far the gripper's proxies reach around the tool frame G (m, in G, gripper open).

    ``below``: deepest point under G's x-y plane (positive number); ``ahead``: furthest point
    ahead of G along its x-axis.
    """

    below: float
    ahead: float


def _shape_points(shape) -> tuple[np.ndarray, float]:
    """Points (in the geometry frame) whose hull, grown by the returned radius, is the shape."""
    if isinstance(shape, Capsule):
        half = shape.length() / 2
        return np.array([[0.0, 0.0, -half], [0.0, 0.0, half]]), shape.radius()
    if isinstance(shape, Sphere):
        return np.zeros((1, 3)), shape.radius()
    if isinstance(shape, Box):
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        return corners * shape.size() / 2, 0.0
    raise TypeError(f"unsupported gripper proxy shape {type(shape).__name__}")


def gripper_extent(world: World) -> GripperExtent:
    """The extent of the proxies rigidly attached to the tool frame, fingers fully open."""
    plant = world.plant
    context = plant.CreateDefaultContext()
    opening = pr2.GRIPPER_MAX_OPENING
    world.set_robot_positions(context, world.robot_q(np.zeros(ARM_DOF), opening))
    inspector = world.scene_graph.model_inspector()
    X_GW = world.tool_frame.CalcPoseInWorld(context).inverse()
    below, ahead = 0.0, 0.0
    for name in _GRIPPER_LINKS:
        body = plant.GetBodyByName(name, world.robot)
        X_GB = X_GW @ plant.EvalBodyPoseInWorld(context, body)
        for gid in inspector.GetGeometries(plant.GetBodyFrameIdOrThrow(body.index()),
                                           Role.kProximity):
            points, radius = _shape_points(inspector.GetShape(gid))
            X_GGeo = X_GB @ inspector.GetPoseInFrame(gid)
            p_G = X_GGeo.multiply(points.T)
            below = max(below, radius - p_G[2].min())
            ahead = max(ahead, p_G[0].max() + radius)
    return GripperExtent(below=below, ahead=ahead)


def grasp_height(scene: Scene, config: BaselineConfig, extent: GripperExtent) -> float:
    """h (m above the board top): ``grasp_height_fraction`` of the target's height, raised if
    needed so the gripper's proxies clear the board by ``d_safe + pose_clearance``."""
    lowest = extent.below + config.d_safe + config.pose_clearance
    return max(config.grasp_height_fraction * scene.target_box.size[2], lowest)


@dataclass(frozen=True)
class ApproachPoses:
    """The two gripper poses of one approach angle (X_WG, tool frame in W) and the height h."""

    alpha: float
    height: float
    X_WStart: RigidTransform
    X_WPregrasp: RigidTransform


def grasp_offset(config: BaselineConfig) -> float:
    """How far (m, along the approach x_G) G lies ahead of the gripper point that goes on the
    target's centre (``config.grasp_point``): the pads' centre, or G itself (0)."""
    return pr2.PADS_BEHIND_TOOL if config.grasp_point == "pads" else 0.0


def approach_poses(scene: Scene, alpha: float, config: BaselineConfig,
                   extent: GripperExtent) -> ApproachPoses:
    """Start and pre-grasp poses of G for approach angle ``alpha`` (see the module docstring)."""
    h = grasp_height(scene, config, extent)
    target = scene.target_box
    d = approach_direction(alpha)
    p_WPre = (np.array([target.pose[0], target.pose[1], scene.shelf.top_height + h])
              + grasp_offset(config) * d)
    x_line = scene.shelf.front_x - extent.ahead - config.d_safe - config.pose_clearance
    back = max(0.0, (p_WPre[0] - x_line) / d[0])
    R_WG = gripper_rotation(alpha)
    return ApproachPoses(alpha, h, RigidTransform(R_WG, p_WPre - back * d),
                         RigidTransform(R_WG, p_WPre))


@dataclass
class IkResult:
    """An IK outcome: the 7 arm angles (rad) or None, the solver used, and the time (s)."""

    q: np.ndarray | None
    solver: str
    seconds: float
    reason: str = ""


class PoseIk:
    """Inverse kinematics of the tool frame in one static planning world, clear of the shelf.

    Each solve: G at ``X_WG`` (position within ``ik_position_tolerance``, orientation within
    ``ik_orientation_tolerance``), arm joint limits (continuous joints within +-pi of
    ``q_near`` when given, else of the seed), the fingers open, every arm-vs-shelf signed
    distance at least ``ik_min_distance``, and a small cost pulling towards ``q_near`` (when
    given) so that paired solutions stay on one branch. SNOPT is tried first, then IPOPT;
    every seed in turn until one succeeds.
    """

    def __init__(self, world: World, config: BaselineConfig):
        self.world, self.config = world, config
        self.root = world.diagram.CreateDefaultContext()
        self.plant_context = world.plant.GetMyMutableContextFromRoot(self.root)
        self.solvers = [(name, s) for name, s in (("snopt", SnoptSolver()),
                                                   ("ipopt", IpoptSolver()))
                        if s.available() and s.enabled()]
        if not self.solvers:
            raise RuntimeError("neither SNOPT nor IPOPT is available in this drake build")
        lower = np.array([lo for lo, _ in pr2.arm_joint_limits().values()])
        upper = np.array([hi for _, hi in pr2.arm_joint_limits().values()])
        self.lower, self.upper = lower, upper
        self.fingers = np.full(2, pr2.finger_joint_position(pr2.GRIPPER_MAX_OPENING))

    def _program(self, X_WG: RigidTransform, seed: np.ndarray, q_near: np.ndarray | None,
                 clear_of_shelf: bool):
        config, world = self.config, self.world
        ik = InverseKinematics(world.plant, self.plant_context, with_joint_limits=False)
        q = ik.q()
        p = X_WG.translation()
        tol = config.ik_position_tolerance
        ik.AddPositionConstraint(world.tool_frame, np.zeros(3), world.plant.world_frame(),
                                 p - tol, p + tol)
        ik.AddOrientationConstraint(world.plant.world_frame(), X_WG.rotation(),
                                    world.tool_frame, RotationMatrix(),
                                    config.ik_orientation_tolerance)
        if clear_of_shelf:
            ik.AddMinimumDistanceLowerBoundConstraint(config.ik_min_distance,
                                                      config.ik_influence_distance)
        prog = ik.get_mutable_prog()
        index = world.robot_position_indices()
        arm = q[index[:ARM_DOF]]
        lower, upper, seed = self._bounds_and_seed(seed, q_near)
        prog.AddBoundingBoxConstraint(lower, upper, arm)
        finger = pr2.finger_joint_position(pr2.GRIPPER_MAX_OPENING)
        prog.AddBoundingBoxConstraint(finger, finger, q[index[ARM_DOF:]])
        if q_near is not None:
            prog.AddQuadraticErrorCost(config.ik_near_weight * np.eye(ARM_DOF), q_near, arm)
        q_guess = np.zeros(world.plant.num_positions())
        q_guess[index] = np.concatenate([seed, self.fingers])
        prog.SetInitialGuess(q, q_guess)
        return prog, arm

    def _bounds_and_seed(self, seed: np.ndarray, q_near: np.ndarray | None):
        """Joint bounds, continuous joints within pi of ``q_near`` (else of the seed, so no
        solution jumps a turn), and the seed wrapped and clipped into them."""
        lower, upper = self.lower.copy(), self.upper.copy()
        centre = seed if q_near is None else q_near
        seed = seed.copy()
        for i in CONTINUOUS_JOINTS:
            lower[i], upper[i] = centre[i] - np.pi, centre[i] + np.pi
            seed[i] = centre[i] + (seed[i] - centre[i] + np.pi) % (2 * np.pi) - np.pi
        return lower, upper, np.clip(seed, lower, upper)

    def _attempt(self, solver_name: str, X_WG, seed, q_near, clear_of_shelf: bool):
        """One solve; the arm angles or None."""
        solver = dict(self.solvers)[solver_name]
        prog, arm = self._program(X_WG, np.asarray(seed, dtype=float), q_near, clear_of_shelf)
        try:
            with quiet_drake_warnings():
                result = solver.Solve(prog, None, self._options(solver_name))
        except RuntimeError:  # a solver error counts as no solution from this seed
            return None
        return result.GetSolution(arm) if result.is_success() else None

    def solve(self, X_WG: RigidTransform, seeds: list[np.ndarray],
              q_near: np.ndarray | None = None, clear_of_shelf: bool = True) -> IkResult:
        """Arm angles putting G at ``X_WG`` (see the class docstring); never raises on failure.

        Per seed, the first solver finds a kinematic solution (no distance constraint, cheap),
        then the full problem is solved from it; if every seed fails, the fallback solver
        (IPOPT when SNOPT is first) gets one try at the full problem from the first seed.
        ``clear_of_shelf=False`` returns the first kinematic solution (shelf ignored).
        """
        start = time.perf_counter()
        first = self.solvers[0][0]
        reached = 0
        for seed in seeds:
            q_kin = self._attempt(first, X_WG, seed, q_near, clear_of_shelf=False)
            if q_kin is not None and not clear_of_shelf:
                return IkResult(q_kin, first, time.perf_counter() - start)
            if q_kin is None:
                continue
            reached += 1
            q = self._attempt(first, X_WG, q_kin, q_near, clear_of_shelf=True)
            if q is not None:
                return IkResult(q, first, time.perf_counter() - start)
        for name, _ in self.solvers[1:]:
            q = self._attempt(name, X_WG, seeds[0], q_near, clear_of_shelf)
            if q is not None:
                return IkResult(q, name, time.perf_counter() - start)
        why = (f"pose reached from {reached} of {len(seeds)} seeds but never "
               f"{self.config.ik_min_distance} m clear of the shelf" if reached
               else f"pose out of reach from all {len(seeds)} seeds")
        return IkResult(None, "", time.perf_counter() - start, why)

    def _options(self, name: str) -> SolverOptions:
        options = SolverOptions()
        if name == "snopt":
            options.SetOption(SnoptSolver.id(), "Major iterations limit",
                              self.config.ik_max_iterations)
        else:
            options.SetOption(IpoptSolver.id(), "max_iter", self.config.ik_max_iterations)
            options.SetOption(IpoptSolver.id(), "print_level", 0)
        return options


def ik_seeds(config: BaselineConfig, first: list[np.ndarray], index: int) -> list[np.ndarray]:
    """Seeds to try in order: ``first`` (e.g. a neighbour's solution), the nominal postures of
    the configuration, then ``ik_random_seeds`` postures drawn uniformly within the joint limits
    (continuous joints within +-pi) from ``ik_seed + index``."""
    seeds = [np.asarray(s, dtype=float) for s in first if s is not None]
    seeds += [np.asarray(s, dtype=float) for s in config.ik_nominal_postures]
    limits = np.array(list(pr2.arm_joint_limits().values()))
    limits = np.clip(limits, -np.pi, np.pi)
    rng = np.random.default_rng(config.ik_seed + index)
    seeds += list(rng.uniform(limits[:, 0], limits[:, 1], (config.ik_random_seeds, ARM_DOF)))
    return seeds


def end_configurations(ik: PoseIk, poses: ApproachPoses, config: BaselineConfig,
                       previous: list[np.ndarray], index: int, timings: dict):
    """IK of the pre-grasp and start poses (W) of angle ``index``: (q_start, q_end, the two
    solvers' names), or the reason one failed (str). ``previous``: the pre-grasp solutions of
    the angles planned before (the last seeds this one; this one's is appended);
    ``timings["ik"]`` gets the seconds."""
    end = ik.solve(poses.X_WPregrasp, ik_seeds(config, previous[-1:], index))
    timings["ik"] = end.seconds
    if end.q is None:
        return f"pre-grasp pose: {end.reason}"
    previous.append(end.q)
    start = ik.solve(poses.X_WStart, ik_seeds(config, [end.q], index), q_near=end.q)
    timings["ik"] += start.seconds
    if start.q is None:
        return f"start pose: {start.reason}"
    # The start was pulled towards the pre-grasp solution; pull a pre-grasp solution back
    # towards the start too and keep it if the pair is closer (the same IK branch).
    closer = ik.solve(poses.X_WPregrasp, [start.q, end.q], q_near=start.q)
    timings["ik"] += closer.seconds
    if closer.q is not None and (np.linalg.norm(closer.q - start.q)
                                 < np.linalg.norm(end.q - start.q)):
        end = closer
    return start.q, end.q, [start.solver, end.solver]
