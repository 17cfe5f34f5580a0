"""Drake worlds built from a `Scene`: the kinematic planning world and the dynamics world phi.

Notation (Drake monogram): ``X_WB`` is the pose of frame B in the world frame W, ``p_WB`` a
position; metres, radians, seconds. W is the scene's world frame (see `scenes`).

* `build_planning_world` - a continuous MultibodyPlant + SceneGraph for IK and distance
  queries (Sec. IV): the PR2 base welded at the scene's placement, the torso welded at the
  scene's lift (the prismatic torso joint is removed), the shelf welded, every box a free body
  at its resting pose. Collision filters leave only arm-vs-obstacle pairs: the robot's own
  links, box-box and box-shelf pairs are filtered out.
* `build_dynamics_world` - phi of Sec. V: a discrete SAP plant with compliant-hydroelastic
  boxes on a rigid shelf; every arm and finger joint has a stiff PD actuator that tracks the
  desired state fed to the plant's desired-state port (the arm is kinematic in the paper;
  stiff implicit PD is its stand-in, and the robot feels no gravity). Stepping is a direct
  discrete update of the plant context (no Simulator).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    Capsule,
    CollisionFilterDeclaration,
    GeometrySet,
    ProximityProperties,
    RoleAssign,
    Sphere,
)
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import (
    ContactModel,
    CoulombFriction,
    DiscreteContactApproximation,
    MultibodyPlant,
)
from pydrake.multibody.tree import (
    JointActuatorIndex,
    ModelInstanceIndex,
    PdControllerGains,
    PrismaticJoint,
    SpatialInertia,
)
from pydrake.planning import RobotDiagram, RobotDiagramBuilder
from pydrake.systems.framework import Context

from drake_clutter.common.config import WorldConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import BoxObject, Scene
from drake_clutter.scene.shelf import SHELF_FRICTION, SHELF_LINK, shelf_sdf

ROBOT_JOINTS = pr2.ARM_JOINTS + pr2.FINGER_JOINTS


@dataclass
class World:
    """A built Drake world: the diagram, its plant and the handles the planners need."""

    scene: Scene
    variant: str
    diagram: RobotDiagram
    plant: MultibodyPlant
    robot: ModelInstanceIndex
    shelf: ModelInstanceIndex
    boxes: ModelInstanceIndex
    box_names: tuple[str, ...]

    @property
    def scene_graph(self):
        """The SceneGraph of the diagram."""
        return self.diagram.scene_graph()

    @property
    def tool_frame(self):
        """The gripper's tool frame (between the fingertips, Sec. III's pre-grasp point)."""
        return self.plant.GetFrameByName(pr2.TOOL_FRAME, self.robot)

    def box_body(self, name: str):
        """The free body of a scene box."""
        return self.plant.GetBodyByName(name, self.boxes)

    def joint_position_index(self, joint_name: str) -> int:
        """Index of a robot joint's position in the plant's full position vector."""
        return self.plant.GetJointByName(joint_name, self.robot).position_start()

    def robot_q(self, arm_q, opening: float) -> np.ndarray:
        """Robot position vector (ROBOT_JOINTS order) from 7 arm angles and a gripper gap (m)."""
        finger = pr2.finger_joint_position(opening)
        return np.concatenate([np.asarray(arm_q, dtype=float), [finger, finger]])

    def set_robot_positions(self, plant_context: Context, q_robot) -> None:
        """Sets the 9 robot joint positions (ROBOT_JOINTS order) in a plant context."""
        q = self.plant.GetPositions(plant_context)
        q[self.robot_position_indices()] = q_robot
        self.plant.SetPositions(plant_context, q)

    def robot_position_indices(self) -> np.ndarray:
        """Indices of the ROBOT_JOINTS positions in the plant's full position vector."""
        return np.array([self.joint_position_index(name) for name in ROBOT_JOINTS])

    def robot_positions(self, plant_context: Context) -> np.ndarray:
        """The 9 robot joint positions (ROBOT_JOINTS order) of a plant context."""
        return self.plant.GetPositions(plant_context)[self.robot_position_indices()]

    def X_WBox(self, plant_context: Context, name: str) -> RigidTransform:
        """Pose of a box in W."""
        return self.plant.EvalBodyPoseInWorld(plant_context, self.box_body(name))


def box_rest_pose(scene: Scene, box: BoxObject) -> RigidTransform:
    """X_WB of a box resting on the board at its planar pose."""
    x, y, yaw = box.pose
    return RigidTransform(RollPitchYaw(0, 0, yaw), [x, y, scene.box_center_z(box)])


def _actuators(plant: MultibodyPlant, instance: ModelInstanceIndex) -> list:
    """The joint actuators of a model instance (works before Finalize, unlike
    GetJointActuatorIndices)."""
    found = []
    for i in range(plant.num_actuators() + 16):  # indices of removed actuators are skipped
        index = JointActuatorIndex(i)
        if plant.has_joint_actuator(index):
            actuator = plant.get_joint_actuator(index)
            if actuator.model_instance() == instance:
                found.append(actuator)
    return found


def _add_robot(builder: RobotDiagramBuilder, scene: Scene, variant: str) -> ModelInstanceIndex:
    plant = builder.plant()
    (robot,) = builder.parser().AddModelsFromString(pr2.urdf_text(variant), "urdf")
    x, y, yaw = scene.robot.base_pose
    base = plant.GetFrameByName(pr2.BASE_LINK, robot)
    plant.WeldFrames(plant.world_frame(), base, RigidTransform(RollPitchYaw(0, 0, yaw),
                                                               [x, y, 0.0]))
    torso_joint = plant.GetJointByName(pr2.TORSO_JOINT, robot)
    torso_child = torso_joint.child_body().body_frame()
    for actuator in _actuators(plant, robot):
        if actuator.joint().name() == pr2.TORSO_JOINT:
            plant.RemoveJointActuator(actuator)
    plant.RemoveJoint(torso_joint)
    plant.WeldFrames(base, torso_child,
                     RigidTransform(pr2.X_BaseTorso(scene.robot.torso_height)))
    return robot


def _add_shelf(builder: RobotDiagramBuilder, scene: Scene, friction: float = SHELF_FRICTION,
               board_depth: float | None = None) -> ModelInstanceIndex:
    plant = builder.plant()
    sdf = shelf_sdf(scene.shelf, friction, board_depth)
    (shelf,) = builder.parser().AddModelsFromString(sdf, "sdf")
    cx, cy = scene.shelf.center_xy
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(SHELF_LINK, shelf),
                     RigidTransform([cx, cy, scene.shelf.top_height]))
    return shelf


def drake_pair_friction(a: float, b: float) -> float:
    """Drake's Coulomb coefficient of a contact between geometries of coefficients a and b:
    2ab / (a + b) (0 when both are 0)."""
    return 2.0 * a * b / (a + b) if a + b > 0 else 0.0


def box_friction(mu: float, config: WorldConfig) -> float:
    """The Coulomb coefficient a box of scene friction ``mu`` gets in Drake: ``mu`` itself,
    or with ``config.friction_as_bullet`` the one whose Drake pair with the shelf and the arm
    (coefficient SHELF_FRICTION), 2ab / (a + b), is Bullet's pair ``mu`` * SHELF_FRICTION
    (Bullet multiplies coefficients); where no such coefficient exists, ``mu``."""
    target = mu * SHELF_FRICTION
    if not config.friction_as_bullet or target >= 2.0 * SHELF_FRICTION:
        return mu
    return target * SHELF_FRICTION / (2.0 * SHELF_FRICTION - target)


def _box_proximity(box: BoxObject, config: WorldConfig, compliant: bool) -> ProximityProperties:
    props = ProximityProperties()
    mu = box_friction(box.friction, config)
    AddContactMaterial(dissipation=config.hunt_crossley_dissipation,
                       point_stiffness=config.point_stiffness,
                       friction=CoulombFriction(mu, mu), properties=props)
    if compliant:
        AddCompliantHydroelasticProperties(config.resolution_hint, config.hydroelastic_modulus,
                                           props)
        if config.hydroelastic_margin > 0:
            props.AddProperty("hydroelastic", "margin", config.hydroelastic_margin)
        props.AddProperty("material", "relaxation_time", config.relaxation_time)
    return props


@dataclass(frozen=True)
class PointContactBoxes:
    """Boxes whose support on the shelf is point contact on small spheres (phi variants).

    By default a sphere of ``sphere_radius`` sits inside each of a box's 8 corners, flush with
    its faces, and alone touches the shelf (point contact of a Box shape on a board jitters at
    rest; four spheres settle). With ``box_shape`` the Box itself meets the arm and the other
    boxes; without it the corner spheres meet everything and the arm passes through the shelf:
    the variant Drake's AutoDiffXd can step through (it has no Box-Box or Box-Capsule point
    queries).

    With ``compliant_box`` the Box stays a compliant hydroelastic body (with the margin) that
    meets the arm and the other boxes, and the spheres are centred on the box's 12 edges (its
    corners, and points at most ``edge_spacing`` apart along each edge; 0: corners only): the
    box stands on its true footprint, ``sphere_radius`` above the shelf, and a box overhanging
    the board's edge is carried by the points still above it.

    ``board_depth`` (m; None: the shelf's thickness) deepens the board's collision box below
    its top, so that a small sphere driven into it in one step is pushed back up, not through.
    """

    sphere_radius: float
    box_shape: bool = True
    compliant_box: bool = False
    edge_spacing: float = 0.0
    board_depth: float | None = None


def _corner_offsets(box: BoxObject, radius: float) -> np.ndarray:
    half = np.asarray(box.size) / 2 - radius
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return signs * half


def edge_points(size, spacing: float) -> np.ndarray:
    """Points p_BS (m, box frame B at the centre) on a box's 12 edges: its 8 corners and, with
    ``spacing`` > 0, points spread evenly along each edge at most ``spacing`` apart."""
    half = np.asarray(size, dtype=float) / 2
    points = [np.array([sx, sy, sz]) * half for sx in (-1, 1) for sy in (-1, 1)
              for sz in (-1, 1)]
    if spacing > 0:
        for axis in range(3):
            n = int(np.ceil(2 * half[axis] / spacing - 1e-9))
            others = [a for a in range(3) if a != axis]
            for s1, s2 in ((-1, -1), (-1, 1), (1, -1), (1, 1)):
                for k in range(1, n):
                    p = np.zeros(3)
                    p[axis] = -half[axis] + 2 * half[axis] * k / n
                    p[others[0]], p[others[1]] = s1 * half[others[0]], s2 * half[others[1]]
                    points.append(p)
    return np.array(points)


def _sphere_offsets(box: BoxObject, point: PointContactBoxes) -> np.ndarray:
    if point.compliant_box:
        return edge_points(box.size, point.edge_spacing)
    return _corner_offsets(box, point.sphere_radius)


def _register_box_geometry(plant: MultibodyPlant, body, box: BoxObject, config: WorldConfig,
                           compliant: bool, point: PointContactBoxes | None,
                           welded: bool = False) -> dict:
    """Collision geometry of one box; returns the ids as {"box": [...], "spheres": [...]}.
    A ``welded`` box gets no support spheres: they would meet only the shelf, which is welded
    to W as the box is, so Drake never pairs them (a box of only spheres keeps them)."""
    ids = {"box": [], "spheres": []}
    shape = point is None or point.box_shape or point.compliant_box
    if shape:
        hydroelastic = compliant and (point is None or point.compliant_box)
        ids["box"].append(plant.RegisterCollisionGeometry(
            body, RigidTransform(), Box(*box.size), f"{box.name}_collision",
            _box_proximity(box, config, hydroelastic)))
    if point is not None and not (welded and shape):
        for i, p_BS in enumerate(_sphere_offsets(box, point)):
            ids["spheres"].append(plant.RegisterCollisionGeometry(
                body, RigidTransform(p_BS), Sphere(point.sphere_radius),
                f"{box.name}_corner{i}", _box_proximity(box, config, False)))
    return ids


def _add_boxes(builder: RobotDiagramBuilder, scene: Scene, config: WorldConfig,
               compliant: bool, frozen: Mapping[str, RigidTransform] | None = None,
               point: PointContactBoxes | None = None) -> tuple[ModelInstanceIndex, dict]:
    plant = builder.plant()
    instance = plant.AddModelInstance("boxes")
    ids = {"box": [], "spheres": []}
    for box in scene.boxes:
        inertia = SpatialInertia.SolidBoxWithMass(box.mass, *box.size)
        body = plant.AddRigidBody(box.name, instance, inertia)
        welded = frozen is not None and box.name in frozen
        for kind, new in _register_box_geometry(plant, body, box, config, compliant,
                                                point, welded).items():
            ids[kind] += new
        plant.RegisterVisualGeometry(body, RigidTransform(), Box(*box.size),
                                     f"{box.name}_visual", np.asarray(box.color))
        if frozen is not None and box.name in frozen:
            plant.WeldFrames(plant.world_frame(), body.body_frame(), frozen[box.name])
        else:
            plant.SetDefaultFloatingBaseBodyPose(body, box_rest_pose(scene, box))
    return instance, ids


def _geometries(plant: MultibodyPlant, *instances: ModelInstanceIndex) -> GeometrySet:
    ids = []
    for instance in instances:
        for index in plant.GetBodyIndices(instance):
            ids += plant.GetCollisionGeometriesForBody(plant.get_body(index))
    return GeometrySet(ids)


def _filter_non_arm_pairs(world_parts: dict, plant: MultibodyPlant, scene_graph) -> None:
    """Leaves only robot-vs-(shelf, box) collision pairs in the planning world."""
    robot = _geometries(plant, world_parts["robot"])
    obstacles = _geometries(plant, world_parts["shelf"], world_parts["boxes"])
    manager = scene_graph.collision_filter_manager()
    manager.Apply(CollisionFilterDeclaration().ExcludeWithin(robot).ExcludeWithin(obstacles))


def _new_world(builder: RobotDiagramBuilder, scene: Scene, variant: str, config: WorldConfig,
               compliant: bool, frozen: Mapping[str, RigidTransform] | None = None,
               point: PointContactBoxes | None = None) -> dict:
    if variant not in pr2.VARIANTS:
        known = ", ".join(pr2.VARIANTS)
        raise ValueError(f"unknown geometry variant {variant!r} ({known})")
    unknown = sorted(set(frozen or ()) - {b.name for b in scene.boxes})
    if unknown:
        raise ValueError(f"frozen boxes not in the scene: {', '.join(unknown)}")
    board_depth = point.board_depth if point is not None else None
    robot, shelf = _add_robot(builder, scene, variant), _add_shelf(builder, scene,
                                                                    board_depth=board_depth)
    boxes, box_geometry = _add_boxes(builder, scene, config, compliant, frozen, point)
    return {"robot": robot, "shelf": shelf, "boxes": boxes, "box_geometry": box_geometry}


def build_planning_world(scene: Scene, variant: str = "capsules",
                         config: WorldConfig | None = None, meshcat=None) -> World:
    """The kinematic planning world (continuous plant) of ``scene`` with an arm geometry variant.

    With ``meshcat`` (a pydrake Meshcat), illustration geometry is drawn there on publish.
    """
    config = config or WorldConfig()
    builder = RobotDiagramBuilder(time_step=0.0)
    parts = _new_world(builder, scene, variant, config, compliant=False)
    plant = builder.plant()
    plant.Finalize()
    _filter_non_arm_pairs(parts, plant, builder.scene_graph())
    if meshcat is not None:
        _add_meshcat(builder, meshcat)
    diagram = builder.Build()
    return World(scene, variant, diagram, plant, parts["robot"], parts["shelf"], parts["boxes"],
                 tuple(b.name for b in scene.boxes))


def _add_meshcat(builder: RobotDiagramBuilder, meshcat) -> None:
    from pydrake.visualization import AddDefaultVisualization

    AddDefaultVisualization(builder.builder(), meshcat=meshcat)


def _make_pd_actuators(plant: MultibodyPlant, robot: ModelInstanceIndex,
                       config: WorldConfig) -> None:
    """Turns the URDF's actuators into stiff PD servos without effort limits.

    The paper's arm is kinematic (Sec. I); the PR2's real 30 N m limits would let boxes stop
    the arm, so phi lifts them. The evaluation in Bullet is where real limits belong.
    """
    by_joint = {a.joint().name(): a for a in _actuators(plant, robot)}
    for name in ROBOT_JOINTS:
        actuator = by_joint.get(name) or plant.AddJointActuator(
            f"{name}_motor", plant.GetJointByName(name, robot))
        actuator.set_effort_limit(np.inf)
        actuator.set_controller_gains(PdControllerGains(p=config.arm_kp, d=config.arm_kd))


def _filter_point_contact_pairs(parts: dict, plant: MultibodyPlant, scene_graph,
                                point: PointContactBoxes) -> None:
    """Corner spheres touch only the shelf and Box shapes everything but the shelf (with
    ``point.box_shape``). Without Box shapes the spheres touch everything and the arm does not
    touch the shelf: AutoDiffXd penetration queries throw for every Capsule-Box candidate pair,
    even one that does not touch (the AutoDiffXd variant suits paths clear of the shelf)."""
    if not (point.box_shape or point.compliant_box):
        scene_graph.collision_filter_manager().Apply(CollisionFilterDeclaration().ExcludeBetween(
            _geometries(plant, parts["robot"]), _geometries(plant, parts["shelf"])))
        return
    spheres = GeometrySet(parts["box_geometry"]["spheres"])
    box_shapes = GeometrySet(parts["box_geometry"]["box"])
    everything_else = _geometries(plant, parts["robot"])
    everything_else.Add(parts["box_geometry"]["box"])
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(spheres)
        .ExcludeBetween(spheres, everything_else)
        .ExcludeBetween(box_shapes, _geometries(plant, parts["shelf"])))


def _dynamics_builder(config: WorldConfig,
                      point_contact: PointContactBoxes | None) -> RobotDiagramBuilder:
    """A diagram builder whose discrete plant has phi's contact settings (approximation,
    near-rigid threshold, hydroelastic or point contact)."""
    builder = RobotDiagramBuilder(time_step=config.time_step)
    plant = builder.plant()
    plant.set_discrete_contact_approximation({
        "sap": DiscreteContactApproximation.kSap,
        "similar": DiscreteContactApproximation.kSimilar,
        "lagged": DiscreteContactApproximation.kLagged}[config.contact_approximation])
    plant.set_sap_near_rigid_threshold(config.near_rigid_threshold)
    hydroelastic = point_contact is None or point_contact.compliant_box
    plant.set_contact_model(ContactModel.kHydroelasticWithFallback if hydroelastic
                            else ContactModel.kPoint)
    return builder


def _filter_actor_contact(builder: RobotDiagramBuilder, parts: dict, config: WorldConfig,
                          point_contact: PointContactBoxes | None) -> GeometrySet:
    """phi's collision rules for the actor (the arm, or a scripted pusher) in ``parts["robot"]``
    after Finalize: its own parts never touch; with support spheres (``point_contact``) those
    alone meet the shelf; with hydroelastic boxes (also "edges") and
    ``config.robot_hydroelastic`` the actor is rigid hydroelastic and does not touch the shelf.
    Returns the actor's geometry."""
    plant, scene_graph = builder.plant(), builder.scene_graph()
    robot_geometry = _geometries(plant, parts["robot"])
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(robot_geometry))
    if point_contact is not None:
        _filter_point_contact_pairs(parts, plant, scene_graph, point_contact)
    if (point_contact is None or point_contact.compliant_box) and config.robot_hydroelastic:
        _make_rigid_hydroelastic(plant, scene_graph, parts["robot"], config)
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeBetween(robot_geometry,
                                                        _geometries(plant, parts["shelf"])))
    return robot_geometry


def build_dynamics_world(scene: Scene, variant: str = "capsules",
                         config: WorldConfig | None = None, meshcat=None, *,
                         frozen_boxes: Mapping[str, RigidTransform] | None = None,
                         point_contact: PointContactBoxes | None = None,
                         arm_passes: Sequence[str] = ()) -> World:
    """phi's world: discrete SAP, hydroelastic compliant boxes, rigid shelf, PD-tracked arm.

    ``frozen_boxes`` (name -> X_WB) welds those boxes to W at the given poses: static geometry
    that other bodies still touch (phi keeps only the boxes a trajectory can affect dynamic).
    ``point_contact`` replaces the hydroelastic boxes by point-contact ones (see
    `PointContactBoxes`). Without it the boxes carry ``config.hydroelastic_margin`` and, with
    ``config.robot_hydroelastic``, the arm is rigid hydroelastic and does not touch the shelf.
    The arm passes through the boxes named in ``arm_passes`` (they still touch everything else).
    """
    config = config or WorldConfig()
    builder = _dynamics_builder(config, point_contact)
    plant = builder.plant()
    parts = _new_world(builder, scene, variant, config, True, frozen_boxes, point_contact)
    plant.set_gravity_enabled(parts["robot"], False)
    _make_pd_actuators(plant, parts["robot"], config)
    plant.SetUseSampledOutputPorts(False)
    plant.Finalize()
    robot_geometry = _filter_actor_contact(builder, parts, config, point_contact)
    if arm_passes:
        passed = GeometrySet([g for name in arm_passes for g in plant.GetCollisionGeometriesForBody(
            plant.GetBodyByName(name, parts["boxes"]))])
        builder.scene_graph().collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeBetween(robot_geometry, passed))
    if meshcat is not None:
        _add_meshcat(builder, meshcat)
    diagram = builder.Build()
    return World(scene, variant, diagram, plant, parts["robot"], parts["shelf"], parts["boxes"],
                 tuple(b.name for b in scene.boxes))


PUSHER_JOINTS = ("pusher_x", "pusher_y", "pusher_z")


@dataclass(frozen=True)
class CapsulePusher:
    """A scripted pusher for phi's world: a horizontal capsule (axis along W's y) on three
    prismatic joints along W's x, y, z, each a PD servo with the arm's gains (``arm_kp`` N/m,
    ``arm_kd`` N s/m), no gravity; its joint positions are its centre in W."""

    radius: float  # m
    length: float  # m, the cylinder's length along y
    friction: float  # Coulomb coefficient in Drake
    mass: float = 1.0  # kg, of the capsule (each carriage weighs a tenth of it)


def _add_pusher(builder: RobotDiagramBuilder, pusher: CapsulePusher,
                config: WorldConfig) -> ModelInstanceIndex:
    plant = builder.plant()
    instance = plant.AddModelInstance("pusher")
    parent = plant.world_frame()
    for i, name in enumerate(PUSHER_JOINTS):
        last = i == len(PUSHER_JOINTS) - 1
        mass = pusher.mass if last else pusher.mass / 10
        body = plant.AddRigidBody(f"{name}_body", instance,
                                  SpatialInertia.SolidSphereWithMass(mass, pusher.radius))
        axis = np.eye(3)[i]
        joint = plant.AddJoint(PrismaticJoint(name, parent, body.body_frame(), axis))
        actuator = plant.AddJointActuator(f"{name}_motor", joint)
        actuator.set_controller_gains(PdControllerGains(p=config.arm_kp, d=config.arm_kd))
        parent = body.body_frame()
    props = ProximityProperties()
    AddContactMaterial(friction=CoulombFriction(pusher.friction, pusher.friction),
                       properties=props)
    X_BG = RigidTransform(RollPitchYaw(np.pi / 2, 0.0, 0.0), [0.0, 0.0, 0.0])  # axis z -> y
    plant.RegisterCollisionGeometry(body, X_BG, Capsule(pusher.radius, pusher.length),
                                    "pusher_collision", props)
    plant.RegisterVisualGeometry(body, X_BG, Capsule(pusher.radius, pusher.length),
                                 "pusher_visual", np.array([0.3, 0.3, 0.35, 1.0]))
    return instance


def build_pusher_world(scene: Scene, pusher: CapsulePusher, config: WorldConfig | None = None,
                       *, point_contact: PointContactBoxes | None = None,
                       shelf_friction: float = SHELF_FRICTION) -> World:
    """phi's world with a scripted capsule pusher in place of the arm (the contact conformance
    suite): the same plant settings, box geometry, shelf and collision rules as
    `build_dynamics_world`; the shelf's coefficient is ``shelf_friction``. The scene's robot
    placement is ignored; `World.robot` is the pusher's instance (joints `PUSHER_JOINTS`)."""
    config = config or WorldConfig()
    builder = _dynamics_builder(config, point_contact)
    plant = builder.plant()
    board_depth = point_contact.board_depth if point_contact is not None else None
    shelf = _add_shelf(builder, scene, shelf_friction, board_depth)
    boxes, box_geometry = _add_boxes(builder, scene, config, True, None, point_contact)
    parts = {"robot": _add_pusher(builder, pusher, config), "shelf": shelf, "boxes": boxes,
             "box_geometry": box_geometry}
    plant.set_gravity_enabled(parts["robot"], False)
    plant.SetUseSampledOutputPorts(False)
    plant.Finalize()
    _filter_actor_contact(builder, parts, config, point_contact)
    diagram = builder.Build()
    return World(scene, "pusher", diagram, plant, parts["robot"], shelf, boxes,
                 tuple(b.name for b in scene.boxes))


def _make_rigid_hydroelastic(plant: MultibodyPlant, scene_graph, instance: ModelInstanceIndex,
                             config: WorldConfig) -> None:
    """Gives a model instance's collision geometry rigid hydroelastic properties (keeping its
    friction), so that it meets the compliant boxes in hydroelastic contact."""
    inspector = scene_graph.model_inspector()
    for geometry in [g for index in plant.GetBodyIndices(instance)
                     for g in plant.GetCollisionGeometriesForBody(plant.get_body(index))]:
        props = ProximityProperties(inspector.GetProximityProperties(geometry))
        AddRigidHydroelasticProperties(config.resolution_hint, props)
        scene_graph.AssignRole(plant.get_source_id(), geometry, props, RoleAssign.kReplace)


def park_positions(world: World, config: WorldConfig) -> np.ndarray:
    """Robot positions (ROBOT_JOINTS order) of the parked arm: outside the shelf, gripper open."""
    return world.robot_q(config.park_configuration, config.park_gripper_opening)


def set_desired_robot_state(world: World, plant_context: Context, q_desired,
                            v_desired=None) -> None:
    """Feeds the PD actuators' desired state (ROBOT_JOINTS order) in a dynamics world."""
    q_desired = np.asarray(q_desired, dtype=float)
    v_desired = np.zeros_like(q_desired) if v_desired is None else np.asarray(v_desired)
    port = world.plant.get_desired_state_input_port(world.robot)
    port.FixValue(plant_context, np.concatenate([q_desired, v_desired]))


def new_dynamics_context(world: World, q_robot) -> Context:
    """A root (diagram) context of a dynamics world: the robot at rest at ``q_robot`` and told
    to stay there, zero feed-forward actuation, the boxes at their resting poses."""
    root = world.diagram.CreateDefaultContext()
    plant = world.plant
    context = plant.GetMyMutableContextFromRoot(root)
    world.set_robot_positions(context, q_robot)
    plant.get_actuation_input_port().FixValue(context, np.zeros(plant.num_actuated_dofs()))
    set_desired_robot_state(world, context, q_robot)
    return root


def step(world: World, root_context: Context, num_steps: int = 1) -> None:
    """Advances a dynamics world by ``num_steps`` SAP steps of ``time_step`` (root context)."""
    plant = world.plant
    context = plant.GetMyMutableContextFromRoot(root_context)
    for _ in range(num_steps):
        state = plant.EvalUniquePeriodicDiscreteUpdate(context)
        context.SetDiscreteState(state.value())
        root_context.SetTime(root_context.get_time() + plant.time_step())


def contact_pairs(results) -> list[tuple]:
    """(geometry id A, geometry id B, contact force in W, N) of every point and hydroelastic
    contact in a plant's ContactResults (double or AutoDiffXd). Drake gives the force on B for
    a point pair and on A (M) for a hydroelastic one; phi uses only its magnitude."""
    pairs = [(info.point_pair().id_A, info.point_pair().id_B, info.contact_force())
             for info in map(results.point_pair_contact_info,
                             range(results.num_point_pair_contacts()))]
    return pairs + [(info.contact_surface().id_M(), info.contact_surface().id_N(),
                     info.F_Ac_W().translational())
                    for info in map(results.hydroelastic_contact_info,
                                    range(results.num_hydroelastic_contacts()))]
