"""phi's model in MuJoCo (``dynamics.engine: mujoco``), written as MJCF text.

The same model as the Drake phi, in the paper's engine:

* the shelf's parts (`scene.shelf.shelf_boxes`) and the frozen boxes as static boxes;
* each kept box a free body of the scene's size and mass (a solid box's inertia);
* the actor: the PR2 arm as a tree of bodies built from `robot.pr2`'s one kinematic description
  (its joints' origins and axes, the collision shapes of a geometry variant: the planning
  capsules or the sphere gripper), its base placed and its torso fixed where the scene puts
  them; or, for the contact suite, a capsule on three slide joints. The actor's joints carry a
  large armature (``mujoco_arm_armature``) and gravity compensation, and phi sets their
  positions and velocities at every step: kinematic, and the contact solver sees its velocity;
* every pair that may touch an explicit ``<pair>`` with its own Coulomb coefficient (automatic
  contacts are off), so no combination rule is involved: a kept box with the shelf, the actor,
  every other box; a frozen box with the actor. The actor never meets the shelf (as in the
  Drake phi, whose c_static keeps the arm off it). The pairs' margin is 0: MuJoCo's margin
  moves a contact's rest distance (a box sliding on a board with 1 mm margin and gap rides
  1 mm above it, measured), so phi widens it only for its interaction queries
  (`mujoco_phi.MujocoPhi`), never for a step.

Settings are MuJoCo's defaults (Euler, pyramidal cones, 2 ms, solref 0.02 1), the contact
suite's reference setting. With ``mujoco_sleep`` a tree (a box) whose speed stays under
``mujoco_sleep_tolerance`` for MuJoCo's ``mjMINAWAKE`` steps sleeps: it leaves the step (its
contacts with the shelf and other sleepers are not solved) until an awake tree touches it or
its state is written. Frames and units: W, metres, kilograms, seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import numpy as np

from drake_clutter.common.physics_config import DynamicsConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import Scene, SceneError, Shelf
from drake_clutter.scene.shelf import SHELF_FRICTION, shelf_boxes

BOARD = "board"  # pair name of the shelf (all its parts)
ACTOR = "actor"  # pair name of the arm or the suite's capsule
TORSIONAL_FRICTION = 0.005  # MJCF friction[1] (unused with condim 3): MuJoCo's default
ROLLING_FRICTION = 0.0001  # MJCF friction[2:4] (unused with condim 3): MuJoCo's default
MIN_FRICTION = 1e-5  # MuJoCo's mjMINMU: it raises a smaller pair coefficient to this
MIN_MASS = 1e-15  # kg, MuJoCo's mjMINVAL: the least mass (and inertia) of a moving body
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _v(values) -> str:
    return " ".join(f"{float(v)!r}" for v in values)


def shelf_geom(part: str) -> str:
    """Geometry name of a shelf part."""
    return f"shelf/{part}"


def box_geom(name: str) -> str:
    """Geometry (and body) name of a scene box."""
    return f"box/{name}"


@dataclass(frozen=True)
class ModelBox:
    """A box of the model: full ``size`` (m), ``mass`` (kg), ``pose`` (quaternion wxyz of
    R_WB, p_WB) and whether it is a free body (``dynamic``) or static."""

    name: str
    size: tuple[float, float, float]
    mass: float
    pose: tuple[float, ...]
    dynamic: bool


@dataclass(frozen=True)
class Actor:
    """The kinematic actor: its bodies' MJCF (children of the world body), its geometry
    names and its joints in command order."""

    xml: str
    geoms: tuple[str, ...]
    joints: tuple[str, ...]


def _shape_geom(name: str, shape: pr2.Shape) -> str:
    """One `pr2.Shape` (link frame) as an MJCF geom."""
    at = np.asarray(shape.xyz, dtype=float)
    head = f"<geom name={quoteattr(name)} contype=\"0\" conaffinity=\"0\" "
    if shape.kind == "sphere":
        return head + f'type="sphere" pos="{_v(at)}" size="{shape.size[0]!r}"/>'
    if shape.kind == "box":
        return head + f'type="box" pos="{_v(at)}" size="{_v(np.array(shape.size) / 2)}"/>'
    radius, length = shape.size
    half = np.asarray(_AXES[shape.axis]) * length / 2
    return (head + f'type="{shape.kind}" fromto="{_v(np.concatenate([at - half, at + half]))}" '
            f'size="{radius!r}"/>')


def _moving_body_head(name: str, pos) -> str:
    return (f"<body name={quoteattr(name)} pos=\"{_v(pos)}\" gravcomp=\"1\">"
            f'<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>')


def arm_actor(scene: Scene, variant: str, armature: float) -> Actor:
    """The PR2 arm of `robot.pr2` (geometry ``variant``) at the scene's robot placement: the
    base and torso static (the torso at ``scene.robot.torso_height``), the seven arm joints
    and two finger slides moving (`worlds.drake_world.ROBOT_JOINTS` order); only the moving
    links carry geometry (the base and torso are never near the shelf's boxes)."""
    shapes = pr2.collision_shapes(variant)
    children: dict[str, list[pr2.Joint]] = {}
    for joint in pr2.JOINTS:
        children.setdefault(joint.parent, []).append(joint)
    geoms: list[str] = []

    def body(joint: pr2.Joint, moving: bool) -> str:
        link = joint.child
        pos = np.asarray(joint.xyz, dtype=float)
        if joint.name == pr2.TORSO_JOINT:
            pos = pos + np.asarray(joint.axis) * scene.robot.torso_height
        moves = joint.type != "fixed" and joint.name != pr2.TORSO_JOINT
        moving = moving or moves
        parts = [_moving_body_head(link, pos) if moving
                 else f"<body name={quoteattr(link)} pos=\"{_v(pos)}\">"]
        if moves:
            kind = "slide" if joint.type == "prismatic" else "hinge"
            parts.append(f"<joint name={quoteattr(joint.name)} type=\"{kind}\" "
                         f"axis=\"{_v(joint.axis)}\" armature=\"{armature!r}\"/>")
        if moving:
            for i, shape in enumerate(shapes.get(link, ())):
                geoms.append(f"arm/{link}/{i}")
                parts.append(_shape_geom(geoms[-1], shape))
        parts += [body(child, moving) for child in children.get(link, ())]
        return "".join(parts) + "</body>"

    x, y, yaw = scene.robot.base_pose
    quat = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
    root = (f"<body name={quoteattr(pr2.BASE_LINK)} pos=\"{_v((x, y, 0.0))}\" "
            f"quat=\"{_v(quat)}\">"
            + "".join(body(j, False) for j in children[pr2.BASE_LINK]) + "</body>")
    joints = pr2.ARM_JOINTS + pr2.FINGER_JOINTS
    return Actor(root, tuple(geoms), joints)


def capsule_actor(radius: float, length: float, start, armature: float) -> Actor:
    """A capsule of ``radius`` and cylinder ``length`` (m) along W's y, centred at ``start``
    (W) on slide joints along W's x, y, z (the contact suite's pusher)."""
    half = length / 2
    xml = (_moving_body_head(ACTOR, start)
           + "".join(f'<joint name="actor_{a}" type="slide" axis="{_v(_AXES[a])}" '
                     f'armature="{armature!r}"/>' for a in "xyz")
           + f'<geom name="actor" type="capsule" fromto="0 {-half!r} 0 0 {half!r} 0" '
           f'size="{radius!r}" contype="0" conaffinity="0"/></body>')
    return Actor(xml, ("actor",), ("actor_x", "actor_y", "actor_z"))


def _box_xml(box: ModelBox) -> str:
    quat, pos = box.pose[:4], box.pose[4:7]
    geom = (f"<geom name={quoteattr(box_geom(box.name))} type=\"box\" "
            f"size=\"{_v(np.array(box.size) / 2)}\" contype=\"0\" conaffinity=\"0\"/>")
    if not box.dynamic:
        return geom.replace("/>", f' pos="{_v(pos)}" quat="{_v(quat)}"/>')
    a, b, c = box.size
    inertia = box.mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    return (f"<body name={quoteattr(box_geom(box.name))} pos=\"{_v(pos)}\" "
            f"quat=\"{_v(quat)}\"><freejoint/><inertial pos=\"0 0 0\" mass=\"{box.mass!r}\" "
            f"diaginertia=\"{_v(inertia)}\"/>{geom}</body>")


def _solver_attributes(config: DynamicsConfig) -> str:
    """A contact's MJCF solref and solimp from the configuration."""
    return (f'solref="{config.mujoco_contact_time!r} {config.mujoco_contact_damping!r}" '
            f'solimp="{config.mujoco_impedance_min!r} {config.mujoco_impedance_max!r} '
            f'{config.mujoco_impedance_width!r} 0.5 2"')


def _pairs(shelf: Shelf, boxes: Sequence[ModelBox], actor: Actor,
           pair_mu: Callable[[str, str], float | None], passes: Sequence[str],
           config: DynamicsConfig) -> list[str]:
    """Every pair that may touch (see the module docstring)."""
    shelf_geoms = [shelf_geom(name) for name, _, _ in shelf_boxes(shelf)]
    settings = f'condim="3" {_solver_attributes(config)}'

    def pair(g1: str, g2: str, mu: float) -> str:
        return (f"<pair geom1={quoteattr(g1)} geom2={quoteattr(g2)} friction=\"{mu!r} {mu!r} "
                f"{TORSIONAL_FRICTION!r} {ROLLING_FRICTION!r} {ROLLING_FRICTION!r}\" "
                f"{settings}/>")

    def pairs(geoms, name: str, box: ModelBox) -> list[str]:
        mu = pair_mu(name, box.name)
        return [] if mu is None else [pair(g, box_geom(box.name), mu) for g in geoms]

    out = []
    for i, box in enumerate(boxes):
        if box.name not in passes:
            out += pairs(actor.geoms, ACTOR, box)
        if not box.dynamic:
            continue
        out += pairs(shelf_geoms, BOARD, box)
        for j, other in enumerate(boxes):
            if j != i and not (other.dynamic and j > i):
                out += pairs([box_geom(other.name)], other.name, box)
    return out


def model_xml(shelf: Shelf, boxes: Sequence[ModelBox], actor: Actor,
              pair_mu: Callable[[str, str], float | None], config: DynamicsConfig,
              knot_time: float, passes: Sequence[str] = ()) -> str:
    """The MJCF text of a model (module docstring): ``pair_mu(a, b)`` is the Coulomb
    coefficient of a pair of names (BOARD, ACTOR or box names; None: the pair never
    touches); the actor does not touch the
    boxes in ``passes``; the time step splits ``knot_time`` into `substeps` equal steps."""
    origin = np.array([*shelf.center_xy, shelf.top_height])
    parts = [f"<geom name={quoteattr(shelf_geom(name))} type=\"box\" "
             f"pos=\"{_v(origin + np.array(centre))}\" size=\"{_v(np.array(size) / 2)}\" "
             f'contype="0" conaffinity="0"/>' for name, centre, size in shelf_boxes(shelf)]
    step = knot_time / substeps(knot_time, config)
    sleep = '<flag sleep="enable"/>' if config.mujoco_sleep else ""
    return (f'<mujoco model="phi"><option timestep="{step!r}" gravity="0 0 -9.81" '
            f'tolerance="{config.mujoco_solver_tolerance!r}" '
            f'ls_tolerance="{config.mujoco_line_search_tolerance!r}" '
            f'sleep_tolerance="{config.mujoco_sleep_tolerance!r}">{sleep}</option>'
            f"<worldbody>{''.join(parts)}{actor.xml}"
            f"{''.join(_box_xml(b) for b in boxes)}"
            f"</worldbody><contact>{''.join(_pairs(shelf, boxes, actor, pair_mu, passes, config))}"
            f"</contact></mujoco>")


def substeps(knot_time: float, config: DynamicsConfig) -> int:
    """MuJoCo steps per knot: the fewest equal steps no longer than ``mujoco_time_step``."""
    return max(1, math.ceil(knot_time / config.mujoco_time_step - 1e-9))


def check_scene(scene: Scene, file: str) -> None:
    """Raises `scenes.SceneError` naming ``file``, the field and the reason where the MuJoCo
    phi cannot realise the scene exactly: a pair coefficient below MuJoCo's least (it would
    raise it silently) or a box lighter than its least mass."""
    pair = scene_pair_friction(scene)
    for i, box in enumerate(scene.boxes):
        others = [pair(other.name, box.name) for other in scene.boxes
                  if other is not box and other.friction >= box.friction]
        lowest = min([pair(BOARD, box.name), *others])
        if lowest < MIN_FRICTION:  # blamed on the box with the smaller coefficient
            raise SceneError(file, f"boxes[{i}].friction",
                             f"{box.friction:g} gives a pair coefficient {lowest:g}, below "
                             f"MuJoCo's least {MIN_FRICTION:g} (dynamics.engine 'mujoco')")
        if box.mass < MIN_MASS:
            raise SceneError(file, f"boxes[{i}].density",
                             f"a mass of {box.mass:g} kg is below MuJoCo's least {MIN_MASS:g} kg "
                             f"(dynamics.engine 'mujoco')")


def scene_pair_friction(scene: Scene) -> Callable[[str, str], float]:
    """The judge's pair coefficients of a scene (Bullet multiplies its bodies' coefficients):
    a box with the shelf or the arm mu_box x SHELF_FRICTION (the Drake phi's arm has the
    shelf's coefficient too), two boxes mu_a x mu_b."""
    mu = {b.name: b.friction for b in scene.boxes}
    mu[BOARD] = mu[ACTOR] = SHELF_FRICTION

    def pair(a: str, b: str) -> float:
        return mu[a] * mu[b]

    return pair
