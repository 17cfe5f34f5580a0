"""The PR2 right arm: one kinematic description, three URDF geometry variants.

Units and frames
----------------
SI units throughout: metres, radians, kilograms, seconds, newtons. Frames follow the PR2/ROS
convention: x forward, y left, z up; at zero joint angles the arm points along +x of
``base_footprint``. Every URDF link frame is its parent joint's frame (joint origin given in
the parent link frame), as in ``pr2_description``; the numbers are those of
``shared/pr2_kinematics.md``. Poses use monogram notation: ``X_BT`` is the pose of frame T
(``torso_lift_link``) in frame B (``base_footprint``).

Tree: ``base_footprint`` -fixed- ``base_link`` -prismatic z- ``torso_lift_link`` - seven
right-arm joints - ``r_wrist_roll_link`` -fixed- ``r_gripper_palm_link`` -fixed-
``r_gripper_tool_frame`` (0.18 m ahead of the palm, a massless frame link), plus two fingers.
The root is not welded to anything: a Drake user welds ``base_footprint`` to the world (or to
the scene's robot placement), a pybullet user loads it with ``useFixedBase=True``.

Gripper simplification
----------------------
The real PR2 gripper is a revolute finger + fingertip linkage. Here it is two PRISMATIC fingers
on the palm, ``r_gripper_l_finger_joint`` along +y and ``r_gripper_r_finger_joint`` along -y,
each 0..0.045 m, both to be driven to the same value (one opening DOF; no ``<mimic>``, which
Drake honours only in SAP plants). The fingers slide from x = 0.07691 (the real finger joints'
x on the palm). Each pad (0.036 x 0.0085 x 0.022 m) is centred at x = 0.165 with its inner face
at y = +-q, so the gap between the pads is 2 q and an object held at the tool frame (x = 0.18)
sits centred between them. See :func:`finger_joint_position` / :func:`gripper_opening`.

Geometry variants (kinematics, masses and inertias are identical in all three)
---------------------------------------------------------------------------------
* ``capsules``: the planning proxy of the paper's Fig. 3b, every arm link one capsule fitted
  around the (evaluation) outline of the real PR2 link; each finger one thin capsule whose inner
  surface is the pad face, so it never intrudes into the grasp gap.
* ``sphere_gripper``: Fig. 3c, as ``capsules`` but palm and fingers replaced by ONE sphere on
  the palm enclosing the whole gripper at full opening; fingers keep only a visual.
* ``evaluation``: boxes and cylinders closer to the real outline (the replay model, Sec. VI).
The base and the torso column are boxes in all variants (static obstacles).

Drake collision filter groups (``drake:collision_filter_group``; pybullet ignores them) exclude
contacts between arm links around the same joint cluster (shoulder, elbow, wrist + gripper),
whose proxies overlap by construction; MultibodyPlant filters parent/child pairs itself. Every
movable joint has a SimpleTransmission, so Drake creates a JointActuator with its effort limit.

pybullet notes: it keeps fixed-joint links (the tool frame is a link) with default flags; it
loads URDF capsules as true capsules but cylinders as convex meshes unless
``flags=URDF_USE_IMPLICIT_CYLINDER``, and it recomputes inertias from the collision shapes unless
``URDF_USE_INERTIA_FROM_FILE``; a link without ``<inertial>`` would get 1 kg, so pure frames carry
an explicit zero one. The effort limits (30 N m at the shoulder) cannot hold the arm against
gravity (the real PR2 has a spring counterbalance): drive the arm kinematically or with stiff PD.

Regenerate the checked-in files with ``python -m drake_clutter.robot.pr2 --write models/urdf``.
"""

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np

Vec3 = tuple[float, float, float]
GeometryVariant = Literal["capsules", "sphere_gripper", "evaluation"]
VARIANTS: tuple[GeometryVariant, ...] = ("capsules", "sphere_gripper", "evaluation")

MODEL_NAME = "pr2_arm"
BASE_LINK = "base_footprint"
TORSO_JOINT = "torso_lift_joint"
TOOL_FRAME = "r_gripper_tool_frame"
PALM_LINK = "r_gripper_palm_link"
ARM_JOINTS: tuple[str, ...] = (
    "r_shoulder_pan_joint", "r_shoulder_lift_joint", "r_upper_arm_roll_joint",
    "r_elbow_flex_joint", "r_forearm_roll_joint", "r_wrist_flex_joint", "r_wrist_roll_joint")
ARM_DOF = len(ARM_JOINTS)  # the arm's joints, the planners' degrees of freedom
FINGER_JOINTS: tuple[str, str] = ("r_gripper_l_finger_joint", "r_gripper_r_finger_joint")
FINGER_LINKS: tuple[str, str] = ("r_gripper_l_finger_link", "r_gripper_r_finger_link")

SHOULDER_PAN_HEIGHT_AT_ZERO_TORSO = 0.051 + 0.739675  # m, pan axis above the floor
TORSO_LIMITS: tuple[float, float] = (0.0, 0.33)  # m, torso_lift_joint travel
GRIPPER_MAX_OPENING = 0.09  # m, largest gap between the pads' inner faces
TOOL_OFFSET = 0.18  # m, tool frame ahead of the palm frame
FINGER_JOINT_X = 0.07691  # m, x of the finger slides on the palm
PAD_SIZE: Vec3 = (0.036, 0.0085, 0.022)  # m, (along approach, thickness, height)
PAD_CENTER_X = 0.165  # m, pad centre ahead of the palm frame
PADS_BEHIND_TOOL = TOOL_OFFSET - PAD_CENTER_X  # m, the pads' centre behind G along x_G
GRIPPER_SPHERE_CENTER_X = 0.095  # m, sphere proxy centre ahead of the palm frame
GRIPPER_SPHERE_RADIUS = 0.118  # m, encloses palm + fingers at full opening (tested)


@dataclass(frozen=True)
class Shape:
    """A primitive in its link frame; cylinders and capsules run along ``axis``. ``size`` is
    (sx, sy, sz) for a box, (radius, length) for a cylinder or capsule (length of the cylindrical
    part, as URDF, Drake and Bullet all read it) and (radius,) for a sphere."""

    kind: Literal["box", "cylinder", "capsule", "sphere"]
    size: tuple[float, ...]
    xyz: Vec3 = (0.0, 0.0, 0.0)
    axis: Literal["x", "y", "z"] = "z"


@dataclass(frozen=True)
class Link:
    """A link: mass (kg, 0 for a pure frame) and the solid standing in for its inertia."""

    name: str
    mass: float
    body: Shape | None
    material: str


@dataclass(frozen=True)
class Joint:
    """A joint as in URDF: origin of the child frame in the parent frame, axis in the child."""

    name: str
    type: Literal["fixed", "prismatic", "revolute", "continuous"]
    parent: str
    child: str
    xyz: Vec3
    axis: Vec3 = (0.0, 0.0, 1.0)
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0
    effort: float = 0.0


def _along(kind, axis, radius, start, end, at: Vec3 = (0.0, 0.0, 0.0)) -> Shape:
    """A cylinder/capsule on ``axis`` from ``start`` to ``end`` (a capsule's cap centres)."""
    i = "xyz".index(axis)
    centre = list(at)
    centre[i] += 0.5 * (start + end)
    return Shape(kind, (radius, end - start), tuple(centre), axis)


def _box_span(x: tuple[float, float], y: tuple[float, float], z: tuple[float, float]) -> Shape:
    """An axis-aligned box spanning the given closed intervals."""
    spans = (x, y, z)
    return Shape("box", tuple(b - a for a, b in spans), tuple(0.5 * (a + b) for a, b in spans))


def _mirror_y(shapes: Sequence[Shape]) -> tuple[Shape, ...]:
    """The same shapes reflected through the xz plane (left finger -> right finger)."""
    return tuple(replace(s, xyz=(s.xyz[0], -s.xyz[1], s.xyz[2])) for s in shapes)


_X, _Y, _Z, _O = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0)
_L = tuple(name.replace("_joint", "_link") for name in ARM_JOINTS)  # the seven arm links
_F = FINGER_JOINT_X  # finger geometry is written in the left finger's frame (+y = outward)

# Outline of the real PR2 links (evaluation geometry); the inertia bodies are taken from it.
_BASE_BOX = _box_span((-0.325, 0.325), (-0.325, 0.325), (-0.031, 0.269))  # 2..32 cm above floor
_TORSO_BOX = _box_span((-0.30, -0.02), (-0.10, 0.10), (-0.70, 0.05))  # column behind shoulders
_PAN_CYL = _along("cylinder", "z", 0.10, -0.29, 0.06)
_LIFT_CYL = _along("cylinder", "y", 0.085, -0.07, 0.07)
_UPPER_ARM_CYL = _along("cylinder", "x", 0.075, 0.06, 0.33)
_UPPER_ARM_HOUSING = _box_span((-0.01, 0.10), (-0.05, 0.05), (-0.05, 0.05))
_ELBOW_CYL = _along("cylinder", "y", 0.055, -0.05, 0.05)
_FOREARM_CYL = _along("cylinder", "x", 0.05, 0.02, 0.29)
_WRIST_FLEX_CYL = _along("cylinder", "y", 0.04, -0.04, 0.04)
_WRIST_ROLL_CYL = _along("cylinder", "x", 0.035, 0.0, 0.03)
_PALM_BOX = _box_span((0.01, 0.10), (-0.035, 0.035), (-0.025, 0.025))
_PAD = Shape("box", PAD_SIZE, (PAD_CENTER_X - _F, 0.5 * PAD_SIZE[1], 0.0))
_FINGERTIP = _box_span((0.14 - _F, 0.185 - _F), (PAD_SIZE[1], 0.03), (-0.0115, 0.0115))
_FINGER_BAR = _box_span((0.085 - _F, 0.14 - _F), (0.012, 0.03), (-0.01, 0.01))
_FINGER_BODY = _box_span((0.085 - _F, 0.185 - _F), (0.0, 0.03), (-0.0115, 0.0115))

LINKS: tuple[Link, ...] = (
    Link(BASE_LINK, 0.0, None, "pr2_base"),
    Link("base_link", 116.0, _BASE_BOX, "pr2_base"),  # mass: plausible, not in the facts
    Link("torso_lift_link", 36.25, _TORSO_BOX, "pr2_base"),  # idem
    Link(_L[0], 25.8, _PAN_CYL, "pr2_grey"),
    Link(_L[1], 2.75, _LIFT_CYL, "pr2_grey"),
    Link(_L[2], 6.02, _UPPER_ARM_CYL, "pr2_grey"),  # carries the upper arm
    Link(_L[3], 1.90, _ELBOW_CYL, "pr2_grey"),
    Link(_L[4], 2.58, _FOREARM_CYL, "pr2_grey"),  # carries the forearm
    Link(_L[5], 0.614, _WRIST_FLEX_CYL, "pr2_grey"),
    Link(_L[6], 0.1, _WRIST_ROLL_CYL, "pr2_grey"),  # mass: plausible flange
    Link(PALM_LINK, 0.580, _PALM_BOX, "pr2_gripper"),
    Link(TOOL_FRAME, 0.0, None, "pr2_gripper"),
    Link(FINGER_LINKS[0], 0.17 + 0.044, _FINGER_BODY, "pr2_gripper"),  # finger + fingertip
    Link(FINGER_LINKS[1], 0.17 + 0.044, _mirror_y([_FINGER_BODY])[0], "pr2_gripper"),
)

_ARM = 30.0  # N m, shoulder pan/lift, upper-arm roll, elbow, forearm roll
_WRIST = 10.0  # N m, wrist flex and roll
JOINTS: tuple[Joint, ...] = (
    Joint("base_footprint_joint", "fixed", BASE_LINK, "base_link", (0.0, 0.0, 0.051)),
    Joint(TORSO_JOINT, "prismatic", "base_link", "torso_lift_link", (-0.05, 0.0, 0.739675),
          _Z, *TORSO_LIMITS, 0.013, 10000.0),
    Joint(ARM_JOINTS[0], "revolute", "torso_lift_link", _L[0], (0.0, -0.188, 0.0),
          _Z, -2.2854, 0.7146, 2.088, _ARM),
    Joint(ARM_JOINTS[1], "revolute", _L[0], _L[1], (0.1, 0.0, 0.0),
          _Y, -0.5236, 1.3963, 2.082, _ARM),
    Joint(ARM_JOINTS[2], "revolute", _L[1], _L[2], _O, _X, -3.9, 0.8, 3.27, _ARM),
    Joint(ARM_JOINTS[3], "revolute", _L[2], _L[3], (0.4, 0.0, 0.0), _Y, -2.3213, 0.0, 3.3, _ARM),
    Joint(ARM_JOINTS[4], "continuous", _L[3], _L[4], _O, _X, -math.inf, math.inf, 3.6, _ARM),
    Joint(ARM_JOINTS[5], "revolute", _L[4], _L[5], (0.321, 0.0, 0.0),
          _Y, -2.18, 0.0, 3.078, _WRIST),
    Joint(ARM_JOINTS[6], "continuous", _L[5], _L[6], _O, _X, -math.inf, math.inf, 3.6, _WRIST),
    Joint("r_gripper_palm_joint", "fixed", _L[6], PALM_LINK, _O),
    Joint("r_gripper_tool_joint", "fixed", PALM_LINK, TOOL_FRAME, (TOOL_OFFSET, 0.0, 0.0)),
    Joint(FINGER_JOINTS[0], "prismatic", PALM_LINK, FINGER_LINKS[0], (_F, 0.0, 0.0),
          _Y, 0.0, 0.5 * GRIPPER_MAX_OPENING, 0.1, 100.0),
    Joint(FINGER_JOINTS[1], "prismatic", PALM_LINK, FINGER_LINKS[1], (_F, 0.0, 0.0),
          (0.0, -1.0, 0.0), 0.0, 0.5 * GRIPPER_MAX_OPENING, 0.1, 100.0),
)
_MOVABLE = tuple(j for j in JOINTS if j.type != "fixed")

# Arm links per joint cluster whose geometries may overlap by construction (Drake filters).
_FILTER_GROUPS: dict[str, tuple[str, ...]] = {
    "r_shoulder": _L[0:3], "r_elbow": _L[2:5], "r_wrist": (*_L[4:7], PALM_LINK, *FINGER_LINKS)}
_MATERIALS = {"pr2_base": (0.25, 0.25, 0.28, 1.0), "pr2_grey": (0.72, 0.72, 0.74, 1.0),
              "pr2_gripper": (0.35, 0.35, 0.38, 1.0)}  # RGBA: dark base, grey arm, dark gripper


def _geometry(variant: GeometryVariant) -> dict[str, tuple[Shape, ...]]:
    """Collision (and visual) shapes per link for one variant."""
    if variant == "evaluation":
        finger = (_PAD, _FINGERTIP, _FINGER_BAR)
        arm = {_L[0]: (_PAN_CYL,), _L[1]: (_LIFT_CYL,), _L[2]: (_UPPER_ARM_CYL, _UPPER_ARM_HOUSING),
               _L[3]: (_ELBOW_CYL,), _L[4]: (_FOREARM_CYL,), _L[5]: (_WRIST_FLEX_CYL,),
               _L[6]: (_WRIST_ROLL_CYL,), PALM_LINK: (_PALM_BOX,)}
    else:
        # Each capsule encloses the evaluation outline of its link (tests check this).
        r_finger = 0.016  # inner surface on the pad face, y = 0 of the finger frame
        finger = (_along("capsule", "x", r_finger, 0.0955 - _F, 0.1755 - _F,
                         (0.0, r_finger, 0.0)),)
        arm = {
            _L[0]: (_along("capsule", "z", 0.12, -0.224, -0.006),),
            _L[1]: (_along("capsule", "y", 0.09, -0.041, 0.041),),
            _L[2]: (_along("capsule", "x", 0.085, 0.035, 0.29),),
            _L[3]: (_along("capsule", "y", 0.065, -0.016, 0.016),),
            _L[4]: (_along("capsule", "x", 0.055, 0.042, 0.268),),
            _L[5]: (_along("capsule", "y", 0.045, -0.02, 0.02),),
            _L[6]: (_along("capsule", "x", 0.04, 0.005, 0.025),),
            PALM_LINK: (_along("capsule", "x", 0.045, 0.023, 0.087),),
        }
    geometry = {"base_link": (_BASE_BOX,), "torso_lift_link": (_TORSO_BOX,), **arm,
                FINGER_LINKS[0]: finger, FINGER_LINKS[1]: _mirror_y(finger)}
    if variant == "sphere_gripper":
        sphere = Shape("sphere", (GRIPPER_SPHERE_RADIUS,), (GRIPPER_SPHERE_CENTER_X, 0.0, 0.0))
        geometry.update({PALM_LINK: (sphere,), FINGER_LINKS[0]: (), FINGER_LINKS[1]: ()})
    return geometry


def collision_shapes(variant: str) -> dict[str, tuple[Shape, ...]]:
    """Collision shapes per link (link frame, metres) of a geometry variant: what the URDF of
    that variant carries, for a model built in another format (phi's MuJoCo model)."""
    return _geometry(_check_variant(variant))


def _principal_inertia(mass: float, body: Shape) -> Vec3:
    """Principal moments (kg m^2, link axes) of a uniform solid box or cylinder."""
    if body.kind == "box":
        sx, sy, sz = body.size
        return (mass * (sy**2 + sz**2) / 12, mass * (sx**2 + sz**2) / 12,
                mass * (sx**2 + sy**2) / 12)
    if body.kind == "cylinder":
        r, length = body.size
        moments = [mass * (3 * r**2 + length**2) / 12] * 3
        moments["xyz".index(body.axis)] = mass * r**2 / 2
        return tuple(moments)
    raise ValueError(f"no inertia formula for a {body.kind}")


def _num(x: float) -> str:
    text = f"{x:.12g}"
    return "0" if text in ("0", "-0") else text


def _vec(v: Sequence[float]) -> str:
    return " ".join(_num(c) for c in v)


_AXIS_RPY: dict[str, Vec3] = {"x": (0.0, math.pi / 2, 0.0), "y": (math.pi / 2, 0.0, 0.0),
                              "z": (0.0, 0.0, 0.0)}


def _shape_xml(tag: str, name: str, shape: Shape, material: str | None) -> list[str]:
    if shape.kind == "box":
        geometry = f'<box size="{_vec(shape.size)}"/>'
    elif shape.kind == "sphere":
        geometry = f'<sphere radius="{_num(shape.size[0])}"/>'
    else:
        geometry = f'<{shape.kind} radius="{_num(shape.size[0])}" length="{_num(shape.size[1])}"/>'
    lines = [f'    <{tag} name="{name}">',
             f'      <origin xyz="{_vec(shape.xyz)}" rpy="{_vec(_AXIS_RPY[shape.axis])}"/>',
             f"      <geometry>{geometry}</geometry>"]
    if material is not None:
        lines.append(f'      <material name="{material}"/>')
    return [*lines, f"    </{tag}>"]


def _link_xml(link: Link, collisions: Sequence[Shape], visuals: Sequence[Shape]) -> list[str]:
    # A pure frame gets an explicit zero inertial: pybullet gives a link without one 1 kg.
    body = link.body or Shape("box", (0.0, 0.0, 0.0))
    ixx, iyy, izz = _principal_inertia(link.mass, body)
    lines = [f'  <link name="{link.name}">', "    <inertial>",
             f'      <origin xyz="{_vec(body.xyz)}" rpy="0 0 0"/>',
             f'      <mass value="{_num(link.mass)}"/>',
             f'      <inertia ixx="{_num(ixx)}" ixy="0" ixz="0" iyy="{_num(iyy)}" '
             f'iyz="0" izz="{_num(izz)}"/>',
             "    </inertial>"]
    for i, shape in enumerate(visuals):
        lines += _shape_xml("visual", f"{link.name}_visual_{i}", shape, link.material)
    for i, shape in enumerate(collisions):
        lines += _shape_xml("collision", f"{link.name}_collision_{i}", shape, None)
    return [*lines, "  </link>"]


def _joint_xml(joint: Joint) -> list[str]:
    lines = [f'  <joint name="{joint.name}" type="{joint.type}">',
             f'    <parent link="{joint.parent}"/>',
             f'    <child link="{joint.child}"/>',
             f'    <origin xyz="{_vec(joint.xyz)}" rpy="0 0 0"/>']
    if joint.type != "fixed":
        lines.append(f'    <axis xyz="{_vec(joint.axis)}"/>')
        bounds = ("" if joint.type == "continuous"
                  else f'lower="{_num(joint.lower)}" upper="{_num(joint.upper)}" ')
        lines.append(f'    <limit {bounds}effort="{_num(joint.effort)}" '
                     f'velocity="{_num(joint.velocity)}"/>')
    return [*lines, "  </joint>"]


def _transmission_xml(joint: Joint) -> list[str]:
    """A simple transmission, from which Drake makes a JointActuator (effort = joint effort)."""
    hardware = "<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>"
    return [f'  <transmission name="{joint.name}_trans">',
            "    <type>transmission_interface/SimpleTransmission</type>",
            f'    <joint name="{joint.name}">{hardware}</joint>',
            f'    <actuator name="{joint.name}_motor">'
            "<mechanicalReduction>1</mechanicalReduction></actuator>",
            "  </transmission>"]


def _check_variant(variant: str) -> GeometryVariant:
    if variant not in VARIANTS:
        raise ValueError(f"unknown geometry variant {variant!r}; valid variants: {VARIANTS}")
    return variant  # type: ignore[return-value]


def urdf_text(variant: str) -> str:
    """The URDF of the PR2 arm with the given geometry variant (one of :data:`VARIANTS`).

    Raises ValueError, naming the valid variants, for any other name.
    """
    variant = _check_variant(variant)
    collisions = _geometry(variant)
    visuals = collisions | ({n: _geometry("capsules")[n] for n in FINGER_LINKS}  # finger visuals
                            if variant == "sphere_gripper" else {})
    lines = ['<?xml version="1.0"?>',
             f"<!-- Generated by drake_clutter/robot/pr2.py (variant {variant!r}); "
             "do not edit by hand. -->",
             f'<robot name="{MODEL_NAME}" xmlns:drake="http://drake.mit.edu">']
    for name, rgba in _MATERIALS.items():
        lines.append(f'  <material name="{name}"><color rgba="{_vec(rgba)}"/></material>')
    for link in LINKS:
        lines += _link_xml(link, collisions.get(link.name, ()), visuals.get(link.name, ()))
    for joint in JOINTS:
        lines += _joint_xml(joint)
    for joint in _MOVABLE:
        lines += _transmission_xml(joint)
    for group, members in _FILTER_GROUPS.items():
        lines.append(f'  <drake:collision_filter_group name="{group}">')
        lines += [f'    <drake:member link="{m}"/>' for m in members]
        lines += [f'    <drake:ignored_collision_filter_group name="{group}"/>',
                  "  </drake:collision_filter_group>"]
    return "\n".join([*lines, "</robot>", ""])


def repo_root() -> Path:
    """The repository root (the folder holding ``drake_clutter/`` and ``models/``)."""
    return Path(__file__).resolve().parents[2]


def urdf_file(variant: str) -> Path:
    """Path of the checked-in ``models/urdf/pr2_arm_<variant>.urdf`` (not checked to exist)."""
    return repo_root() / "models" / "urdf" / f"pr2_arm_{_check_variant(variant)}.urdf"


def write_urdfs(directory: Path) -> list[Path]:
    """Write ``pr2_arm_<variant>.urdf`` for every variant into ``directory``; return the paths."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    paths = [Path(directory) / f"pr2_arm_{variant}.urdf" for variant in VARIANTS]
    for path, variant in zip(paths, VARIANTS, strict=True):
        path.write_text(urdf_text(variant), encoding="utf-8")
    return paths


def finger_joint_position(opening_m: float) -> float:
    """Each finger's prismatic joint value (m) for a gap ``opening_m`` between the pads.

    Raises ValueError outside [0, GRIPPER_MAX_OPENING] (or for a non-finite value).
    """
    if not 0.0 <= opening_m <= GRIPPER_MAX_OPENING:  # also rejects NaN
        raise ValueError(f"gripper opening {opening_m} m outside [0, {GRIPPER_MAX_OPENING}] m")
    return 0.5 * opening_m


def gripper_opening(q_finger: float) -> float:
    """Gap (m) between the pads when each finger joint is at ``q_finger``.

    The inverse of :func:`finger_joint_position`; it does not clip, so a simulated finger that
    overshoots its limit slightly reports the gap it really has.
    """
    return 2.0 * q_finger


def _joint(name: str) -> Joint:
    return next(j for j in JOINTS if j.name == name)


def arm_joint_limits() -> dict[str, tuple[float, float]]:
    """Position limits (rad) of the seven arm joints; (-inf, inf) for the continuous rolls."""
    return {name: (_joint(name).lower, _joint(name).upper) for name in ARM_JOINTS}


def velocity_limits() -> dict[str, float]:
    """Velocity limits of every movable joint: torso (m/s), arm (rad/s), fingers (m/s each)."""
    return {j.name: j.velocity for j in _MOVABLE}


def effort_limits() -> dict[str, float]:
    """Effort limits of every movable joint: torso and fingers in N, arm joints in N m."""
    return {j.name: j.effort for j in _MOVABLE}


def X_BaseTorso(torso_height: float) -> np.ndarray:
    """4x4 pose of ``torso_lift_link`` in ``base_footprint`` at the given torso lift (m).

    Raises ValueError for a lift outside :data:`TORSO_LIMITS`.
    """
    low, high = TORSO_LIMITS
    if not low <= torso_height <= high:
        raise ValueError(f"torso height {torso_height} m outside [{low}, {high}] m")
    X_BT = np.eye(4)
    X_BT[:3, 3] = np.add(_joint("base_footprint_joint").xyz, _joint(TORSO_JOINT).xyz)
    X_BT[2, 3] += torso_height
    return X_BT


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m drake_clutter.robot.pr2 --write models/urdf``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", type=Path, default=repo_root() / "models" / "urdf",
                        help="folder for pr2_arm_<variant>.urdf (default: models/urdf)")
    args = parser.parse_args(argv)
    for path in write_urdfs(args.write):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
