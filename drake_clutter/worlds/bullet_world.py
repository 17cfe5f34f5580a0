"""The Bullet world of a `Scene`: the hard-contact simulator that judges plans (Sec. III, VI).

The paper replays every plan in Bullet with a mesh robot and hard contacts, "to detect
overfitting to the approximations used in the optimization" (Sec. VI-A). This module builds that
world with pybullet in DIRECT mode, independent of the Drake worlds the planners use:

* the shelf (board, and walls + ceiling for a refrigerator) as one static body with the
  `shelf.shelf_boxes` parts, friction ``shelf.SHELF_FRICTION``;
* a static floor plane at z = 0 (W), so a box that falls off the shelf lands somewhere;
* every scene box as a free rigid box: mass = density x volume, the scene's friction, resting on
  the board at its planar pose, no velocity damping (Bullet's 0.04 default would be a fudge);
* the PR2 arm with its **evaluation** geometry (``models/urdf/pr2_arm_evaluation.urdf``, boxes and
  true cylinders, not the planning capsules), base fixed at the scene's placement, the torso
  prismatic joint held at the scene's lift by a motor. Arm links do not collide with each other.

Frames and units: the pybullet world frame is W (z up, metres, radians, seconds, newtons).
Robot joint vectors here are ``MOTOR_ORDER``: torso lift (m), the seven ``ARM_JOINTS`` (rad),
the two ``FINGER_JOINTS`` (m each, the gap is their sum).

Determinism: each world is a fresh DIRECT client with every engine parameter that matters set
explicitly (some, like the contact breaking threshold, are process-global in Bullet, so a
previous world could otherwise leak its setting), and ``deterministicOverlappingPairs`` on.
Close the world (``with build_bullet_world(...) as world:``) to free the client.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import Scene
from drake_clutter.scene.shelf import SHELF_FRICTION, shelf_boxes


def _import_pybullet_quietly():
    """pybullet announces its build time on stderr when imported; the command line promises one
    line on stderr for a user error, so the announcement goes to the null device."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            return importlib.import_module("pybullet")
    finally:
        os.dup2(saved, 2)
        os.close(saved)


pb = _import_pybullet_quietly()

GRAVITY = 9.81  # m/s^2
MOTOR_ORDER: tuple[str, ...] = (pr2.TORSO_JOINT, *pr2.ARM_JOINTS,
                                *pr2.FINGER_JOINTS)
_URDF_FLAGS = pb.URDF_USE_INERTIA_FROM_FILE | pb.URDF_USE_IMPLICIT_CYLINDER


@dataclass
class BulletWorld:
    """A built pybullet world (one DIRECT client) and the ids the evaluation needs."""

    client: int
    scene: Scene
    robot: int
    shelf: int
    floor: int
    boxes: tuple[int, ...]
    box_names: tuple[str, ...]
    box_masses: np.ndarray  # kg, in scene order
    motor_joints: tuple[int, ...]  # pybullet joint indices in MOTOR_ORDER
    tool_link: int
    link_names: dict[int, str]  # robot link index -> URDF link name (-1: base_footprint)

    def __post_init__(self):
        self.box_index = {body: i for i, body in enumerate(self.boxes)}

    @property
    def static_bodies(self) -> tuple[int, int]:
        """Ids of the immovable bodies S_j of Sec. III (shelf, floor)."""
        return (self.shelf, self.floor)

    def close(self) -> None:
        """Disconnects the client (idempotent)."""
        if self.client >= 0 and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = -1

    def __enter__(self) -> BulletWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def new_client(config: EvaluationConfig) -> int:
    """A fresh pybullet DIRECT client with the judge's engine settings (time step, solver
    iterations, contact breaking threshold, cone friction, deterministic pairs) and gravity."""
    client = pb.connect(pb.DIRECT)
    pb.resetSimulation(physicsClientId=client)
    pb.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=client)
    pb.setPhysicsEngineParameter(
        fixedTimeStep=config.sim_dt, numSubSteps=0, numSolverIterations=config.solver_iterations,
        deterministicOverlappingPairs=1, contactBreakingThreshold=config.contact_breaking_threshold,
        enableConeFriction=1, physicsClientId=client)
    return client


def add_shelf(client: int, scene: Scene, friction: float = SHELF_FRICTION) -> int:
    """The scene's shelf as one static body (board, walls), lateral friction ``friction``."""
    shelf = scene.shelf
    parts = shelf_boxes(shelf)
    shape = pb.createCollisionShapeArray(
        [pb.GEOM_BOX] * len(parts), halfExtents=[[s / 2 for s in size] for _, _, size in parts],
        collisionFramePositions=[list(centre) for _, centre, _ in parts], physicsClientId=client)
    body = pb.createMultiBody(0.0, shape, -1, [*shelf.center_xy, shelf.top_height],
                              useMaximalCoordinates=True, physicsClientId=client)
    pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=client)
    return body


def _add_floor(client: int) -> int:
    shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client)
    body = pb.createMultiBody(0.0, shape, -1, [0.0, 0.0, 0.0], useMaximalCoordinates=True,
                              physicsClientId=client)
    pb.changeDynamics(body, -1, lateralFriction=SHELF_FRICTION, physicsClientId=client)
    return body


def add_boxes(client: int, scene: Scene) -> tuple[int, ...]:
    """The scene's boxes as free bodies resting on the board (scene order): mass, the box's
    friction, no restitution, no velocity damping."""
    ids = []
    for box in scene.boxes:
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[s / 2 for s in box.size],
                                        physicsClientId=client)
        x, y, yaw = box.pose
        body = pb.createMultiBody(box.mass, shape, -1, [x, y, scene.box_center_z(box)],
                                  pb.getQuaternionFromEuler([0.0, 0.0, yaw]),
                                  useMaximalCoordinates=True, physicsClientId=client)
        pb.changeDynamics(body, -1, lateralFriction=box.friction, restitution=0.0,
                          linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
        ids.append(body)
    return tuple(ids)


def _add_robot(client: int, scene: Scene, config: EvaluationConfig):
    x, y, yaw = scene.robot.base_pose
    robot = pb.loadURDF(str(pr2.urdf_file("evaluation")), [x, y, 0.0],
                        pb.getQuaternionFromEuler([0.0, 0.0, yaw]), useFixedBase=True,
                        flags=_URDF_FLAGS, physicsClientId=client)
    joints, links = {}, {-1: pr2.BASE_LINK}
    for j in range(pb.getNumJoints(robot, physicsClientId=client)):
        info = pb.getJointInfo(robot, j, physicsClientId=client)
        joints[info[1].decode()] = j
        links[j] = info[12].decode()
        pb.changeDynamics(robot, j, lateralFriction=config.arm_friction, physicsClientId=client)
    motor_joints = tuple(joints[name] for name in MOTOR_ORDER)
    # calculateJacobian orders the movable joints by index; tool_jacobian relies on MOTOR_ORDER
    # being that order.
    assert list(motor_joints) == sorted(motor_joints), "unexpected joint order in the URDF"
    tool_link = next(i for i, name in links.items() if name == pr2.TOOL_FRAME)
    return robot, motor_joints, tool_link, links


def build_bullet_world(scene: Scene, config: EvaluationConfig | None = None) -> BulletWorld:
    """A fresh pybullet DIRECT world of ``scene``: shelf, floor, boxes at rest, the arm parked
    at zero joint angles with the torso at the scene's lift (see the module docstring)."""
    config = config or EvaluationConfig()
    client = new_client(config)
    try:
        robot, motor_joints, tool_link, links = _add_robot(client, scene, config)
        world = BulletWorld(client, scene, robot, add_shelf(client, scene), _add_floor(client),
                            add_boxes(client, scene), tuple(b.name for b in scene.boxes),
                            np.array([b.mass for b in scene.boxes]), motor_joints, tool_link,
                            links)
    except BaseException:
        pb.disconnect(client)
        raise
    reset_robot(world, np.r_[scene.robot.torso_height, np.zeros(len(MOTOR_ORDER) - 1)])
    return world


def reset_robot(world: BulletWorld, q_motor) -> None:
    """Teleports the robot joints to ``q_motor`` (MOTOR_ORDER) at rest (before simulating)."""
    for joint, q in zip(world.motor_joints, np.asarray(q_motor, dtype=float), strict=True):
        pb.resetJointState(world.robot, joint, float(q), 0.0, physicsClientId=world.client)


def motor_positions(world: BulletWorld, q_robot, torso_height: float | None = None) -> np.ndarray:
    """MOTOR_ORDER vector(s) from ROBOT_JOINTS rows (7 arm angles + 2 finger slides), shape
    (..., 9) -> (..., 10), the torso at ``torso_height`` (default: the scene's lift)."""
    q_robot = np.asarray(q_robot, dtype=float)
    torso = world.scene.robot.torso_height if torso_height is None else torso_height
    return np.concatenate([np.full(q_robot.shape[:-1] + (1,), torso), q_robot], axis=-1)


def joint_positions(world: BulletWorld) -> np.ndarray:
    """The robot's joint positions in MOTOR_ORDER (m, rad)."""
    states = pb.getJointStates(world.robot, world.motor_joints, physicsClientId=world.client)
    return np.array([s[0] for s in states])


def command_velocities(world: BulletWorld, velocities, forces) -> None:
    """Velocity motors on every MOTOR_ORDER joint: target speeds (m/s, rad/s) and the largest
    force/torque (N, N m) each motor may use to reach them; applied from the next step on."""
    pb.setJointMotorControlArray(world.robot, world.motor_joints, pb.VELOCITY_CONTROL,
                                 targetVelocities=list(velocities), forces=list(forces),
                                 physicsClientId=world.client)


def step(world: BulletWorld, num_steps: int = 1) -> None:
    """Advances the simulation by ``num_steps`` fixed steps."""
    for _ in range(num_steps):
        pb.stepSimulation(physicsClientId=world.client)


def box_poses(world: BulletWorld) -> tuple[np.ndarray, np.ndarray]:
    """Box centres p_WB (N, 3) in metres and rotation matrices R_WB (N, 3, 3), scene order."""
    positions, rotations = [], []
    for body in world.boxes:
        p, quat = pb.getBasePositionAndOrientation(body, physicsClientId=world.client)
        positions.append(p)
        rotations.append(pb.getMatrixFromQuaternion(quat))
    return np.array(positions), np.array(rotations).reshape(-1, 3, 3)


def box_speeds(world: BulletWorld) -> tuple[np.ndarray, np.ndarray]:
    """Linear (m/s) and angular (rad/s) speeds of the boxes' centres, scene order."""
    velocities = [pb.getBaseVelocity(body, physicsClientId=world.client) for body in world.boxes]
    v = np.array([lin for lin, _ in velocities]).reshape(-1, 3)
    w = np.array([ang for _, ang in velocities]).reshape(-1, 3)
    return np.linalg.norm(v, axis=1), np.linalg.norm(w, axis=1)


def tool_pose(world: BulletWorld) -> tuple[np.ndarray, np.ndarray]:
    """X_WG of the gripper tool frame: position p_WG (m) and rotation R_WG (3x3)."""
    state = pb.getLinkState(world.robot, world.tool_link, computeForwardKinematics=True,
                            physicsClientId=world.client)
    return np.array(state[4]), np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)


def tool_jacobian(world: BulletWorld, q_motor) -> np.ndarray:
    """6x7 Jacobian of the tool frame's (linear; angular) velocity in W w.r.t. the arm joints."""
    q = [float(v) for v in q_motor]
    zeros = [0.0] * len(q)
    linear, angular = pb.calculateJacobian(world.robot, world.tool_link, [0.0, 0.0, 0.0], q,
                                           zeros, zeros, physicsClientId=world.client)
    return np.vstack([np.array(linear), np.array(angular)])[:, 1:8]


def region_penetrations(world: BulletWorld, half_extents, p_W, R_W,
                        bodies: Sequence[int]) -> list[float]:
    """How deep (m, >= 0) each of ``bodies`` reaches into a box region (centre p_W, rotation R_W,
    half extents, W); 0 for a body clear of it. Uses a temporary collision-only probe body."""
    client = world.client
    half = [max(float(h), 1e-5) for h in half_extents]
    shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=client)
    probe = pb.createMultiBody(0.0, shape, -1, [float(v) for v in p_W],
                               Rotation.from_matrix(np.asarray(R_W)).as_quat().tolist(),
                               physicsClientId=client)
    try:
        depths = []
        for body in bodies:
            points = pb.getClosestPoints(probe, body, 0.0, physicsClientId=client)
            depths.append(max([0.0] + [-point[8] for point in points]))
    finally:
        pb.removeBody(probe, physicsClientId=client)  # (Bullet refuses to drop the shape too)
    return depths


@dataclass(frozen=True)
class ContactSample:
    """Contact normal forces (N) after a step, from Bullet's last solve.

    ``box_static``: per box (scene order), the sum over its contact points with the shelf (the
    floor is left out: a box on the floor has fallen already). ``arm_static`` / ``arm_box``: sums
    over the robot's contact points with static bodies / boxes; ``arm_static_depth`` (m, >= 0) the
    deepest robot-static penetration and ``arm_static_link`` the robot link with the deepest
    (or, without penetration, the most loaded) robot-static contact point.
    """

    box_static: np.ndarray
    arm_static: float
    arm_static_depth: float
    arm_static_link: str
    arm_box: float


def contact_sample(world: BulletWorld) -> ContactSample:
    """The current contact forces of the boxes and the robot (see `ContactSample`)."""
    client, index = world.client, world.box_index
    box_static = np.zeros(len(world.boxes))
    for point in pb.getContactPoints(bodyA=world.shelf, physicsClientId=client):
        i = index.get(point[2])
        if i is not None:
            box_static[i] += point[9]
    arm_static = arm_box = depth = loaded = 0.0
    link = ""
    for point in pb.getContactPoints(bodyA=world.robot, physicsClientId=client):
        if point[2] in world.static_bodies:
            arm_static += point[9]
            if -point[8] > depth or (depth == 0.0 and point[8] >= 0.0 and point[9] > loaded):
                link = world.link_names[point[3]]
                depth, loaded = max(depth, -point[8]), max(loaded, point[9])
        elif point[2] in index:
            arm_box += point[9]
    return ContactSample(box_static, arm_static, depth, link, arm_box)


def touching_links(world: BulletWorld, body: int) -> set[str]:
    """Names of the robot links in contact with ``body`` now."""
    points = pb.getContactPoints(bodyA=world.robot, bodyB=body, physicsClientId=world.client)
    return {world.link_names[point[3]] for point in points}


def motor_forces(config: EvaluationConfig) -> list[float]:
    """Force ceilings in MOTOR_ORDER (N m, N): a kinematic torso and arm (``arm_max_force``),
    the PR2's own finger effort, so a box between the fingers stops them."""
    efforts = pr2.effort_limits()
    return [config.arm_max_force] * 8 + [efforts[name] for name in pr2.FINGER_JOINTS]


def hold(world: BulletWorld, q_hold: np.ndarray, forces, span: float,
         finger_speed: float | None = None) -> None:
    """Commands the motors to be at ``q_hold`` (MOTOR_ORDER) ``span`` seconds from now; with
    ``finger_speed`` (m/s) the fingers close at that speed instead."""
    velocities = (np.asarray(q_hold, dtype=float) - joint_positions(world)) / span
    if finger_speed is not None:
        velocities[8:10] = -finger_speed
    command_velocities(world, velocities, forces)
