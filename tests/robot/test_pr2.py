"""Tests of drake_clutter.robot.pr2: generated URDFs, Drake/pybullet agreement, geometry."""

import math
import xml.etree.ElementTree as ET

import numpy as np
import pybullet as pb
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import PrismaticJoint, RevoluteJoint
from pydrake.systems.framework import DiagramBuilder

from drake_clutter.robot import pr2 as rm

MOVABLE = (rm.TORSO_JOINT, *rm.ARM_JOINTS, *rm.FINGER_JOINTS)
LINKS = tuple(link.name for link in rm.LINKS)
PRISMATIC = {rm.TORSO_JOINT, *rm.FINGER_JOINTS}
Q_FINGER_MAX = rm.GRIPPER_MAX_OPENING / 2


def _add_arm(plant: MultibodyPlant, variant: str) -> None:
    Parser(plant).AddModelsFromString(rm.urdf_text(variant), "urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(rm.BASE_LINK))


def _set_joints(plant, context, values: dict[str, float]) -> None:
    for name, value in values.items():
        joint = plant.GetJointByName(name)
        if isinstance(joint, PrismaticJoint):
            joint.set_translation(context, value)
        else:
            joint.set_angle(context, value)


@pytest.fixture(scope="module", params=rm.VARIANTS)
def variant(request) -> str:
    return request.param


@pytest.fixture(scope="module")
def drake_plant(variant):
    plant = MultibodyPlant(0.0)
    _add_arm(plant, variant)
    plant.Finalize()
    return plant


@pytest.fixture(scope="module")
def bullet(variant):
    """(client, body id, {link name: link index}) of the checked-in URDF; disconnected after."""
    client = pb.connect(pb.DIRECT)
    try:
        uid = pb.loadURDF(str(rm.urdf_file(variant)), useFixedBase=True, physicsClientId=client)
        links = {pb.getJointInfo(uid, i, physicsClientId=client)[12].decode(): i
                 for i in range(pb.getNumJoints(uid, physicsClientId=client))}
        yield client, uid, links
    finally:
        pb.disconnect(client)


def _bullet_joints(client, uid) -> dict[str, tuple]:
    infos = (pb.getJointInfo(uid, i, physicsClientId=client)
             for i in range(pb.getNumJoints(uid, physicsClientId=client)))
    return {info[1].decode(): info for info in infos}


def _root(variant: str) -> ET.Element:
    return ET.fromstring(rm.urdf_text(variant))


# --- generated files ---------------------------------------------------------------------------


def test_checked_in_urdf_matches_generator(variant):
    path = rm.urdf_file(variant)
    assert path.name == f"pr2_arm_{variant}.urdf"
    assert path.read_text(encoding="utf-8") == rm.urdf_text(variant), (
        "regenerate with: python -m drake_clutter.robot.pr2 --write models/urdf")


def test_write_urdfs_and_main(tmp_path):
    paths = rm.write_urdfs(tmp_path / "a")
    assert [p.name for p in paths] == [f"pr2_arm_{v}.urdf" for v in rm.VARIANTS]
    assert rm.main(["--write", str(tmp_path / "b")]) == 0
    for path in paths:
        assert path.read_text() == (tmp_path / "b" / path.name).read_text()


@pytest.mark.parametrize("bad", ["mesh", "", "Capsules"])
def test_unknown_variant_raises(bad):
    with pytest.raises(ValueError, match="capsules.*sphere_gripper.*evaluation"):
        rm.urdf_text(bad)
    with pytest.raises(ValueError, match=repr(bad)):
        rm.urdf_file(bad)


# --- loading in Drake and pybullet -------------------------------------------------------------


def test_drake_loads_tree(drake_plant):
    plant = drake_plant
    assert plant.num_positions() == len(MOVABLE)
    for name in LINKS:
        assert plant.HasBodyNamed(name)
    for name in MOVABLE:
        joint = plant.GetJointByName(name)
        expected = PrismaticJoint if name in PRISMATIC else RevoluteJoint
        assert isinstance(joint, expected), name
    for name, (low, high) in rm.arm_joint_limits().items():
        joint = plant.GetJointByName(name)
        assert (joint.position_lower_limits()[0], joint.position_upper_limits()[0]) == (low, high)
    for name in ("r_forearm_roll_joint", "r_wrist_roll_joint"):
        assert rm.arm_joint_limits()[name] == (-math.inf, math.inf)
    torso = plant.GetJointByName(rm.TORSO_JOINT)
    assert (torso.position_lower_limits()[0], torso.position_upper_limits()[0]) == rm.TORSO_LIMITS
    for name in rm.FINGER_JOINTS:
        finger = plant.GetJointByName(name)
        assert finger.position_lower_limits()[0] == 0.0
        assert finger.position_upper_limits()[0] == pytest.approx(Q_FINGER_MAX, abs=1e-15)
    for name, velocity in rm.velocity_limits().items():
        assert plant.GetJointByName(name).velocity_upper_limits()[0] == velocity
    efforts = {plant.get_joint_actuator(i).joint().name(): plant.get_joint_actuator(i)
               .effort_limit() for i in plant.GetJointActuatorIndices()}
    assert efforts == rm.effort_limits()
    assert set(efforts) == set(MOVABLE)


def test_pybullet_loads_same_joints_as_drake(bullet, drake_plant):
    client, uid, links = bullet
    assert pb.getBodyInfo(uid, physicsClientId=client)[0].decode() == rm.BASE_LINK
    assert set(links) | {rm.BASE_LINK} == set(LINKS)  # fixed links (tool frame) are kept
    joints = _bullet_joints(client, uid)
    assert {n for n, info in joints.items() if info[2] != pb.JOINT_FIXED} == set(MOVABLE)
    for name in MOVABLE:
        info, joint = joints[name], drake_plant.GetJointByName(name)
        assert info[2] == (pb.JOINT_PRISMATIC if name in PRISMATIC else pb.JOINT_REVOLUTE)
        low, high = info[8], info[9]
        if low > high:  # pybullet's encoding of a continuous joint
            low, high = -math.inf, math.inf
        assert low == joint.position_lower_limits()[0]
        assert high == pytest.approx(joint.position_upper_limits()[0], abs=1e-15)
        assert info[11] == pytest.approx(joint.velocity_upper_limits()[0], abs=1e-15)
        assert info[10] == rm.effort_limits()[name]


def test_inertias_are_physically_valid(variant):
    for link in _root(variant).iter("link"):
        attrib = link.find("inertial/inertia").attrib
        i = sorted(float(attrib[k]) for k in ("ixx", "iyy", "izz"))
        mass = float(link.find("inertial/mass").get("value"))
        assert all(float(attrib[k]) == 0.0 for k in ("ixy", "ixz", "iyz"))
        if mass > 0:
            assert i[0] > 0 and i[0] + i[1] >= i[2], link.get("name")
        else:
            assert i == [0.0, 0.0, 0.0] and link.get("name") in (rm.BASE_LINK, rm.TOOL_FRAME)


# --- kinematics --------------------------------------------------------------------------------


def test_zero_configuration_puts_tool_one_metre_ahead_of_the_shoulder():
    plant = MultibodyPlant(0.0)
    _add_arm(plant, "capsules")
    plant.Finalize()
    context = plant.CreateDefaultContext()
    _set_joints(plant, context, dict.fromkeys(MOVABLE, 0.0))
    X_WT = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(rm.TOOL_FRAME))
    X_WS = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("r_shoulder_pan_link"))
    np.testing.assert_allclose(X_WT.translation() - X_WS.translation(), [1.001, 0, 0], atol=1e-9)
    np.testing.assert_allclose(X_WT.translation(), [-0.05 + 1.001, -0.188, 0.790675], atol=1e-9)
    assert rm.SHOULDER_PAN_HEIGHT_AT_ZERO_TORSO == pytest.approx(0.7907, abs=1e-4)
    np.testing.assert_allclose(X_WT.rotation().matrix(), np.eye(3), atol=1e-12)
    for height in (0.0, 0.17, 0.33):
        _set_joints(plant, context, {rm.TORSO_JOINT: height})
        X_WTorso = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("torso_lift_link"))
        np.testing.assert_allclose(rm.X_BaseTorso(height), X_WTorso.GetAsMatrix4(), atol=1e-12)


@pytest.mark.parametrize("height", [-1e-3, 0.331, math.nan])
def test_torso_transform_rejects_out_of_range(height):
    with pytest.raises(ValueError):
        rm.X_BaseTorso(height)


def _random_configuration(rng: np.random.Generator, torso: float) -> dict[str, float]:
    q = {rm.TORSO_JOINT: torso}
    for name, (low, high) in rm.arm_joint_limits().items():
        q[name] = rng.uniform(-2 * math.pi, 2 * math.pi) if math.isinf(low) else rng.uniform(
            low, high)
    q.update(dict.fromkeys(rm.FINGER_JOINTS, rng.uniform(0.0, Q_FINGER_MAX)))
    return q


def test_drake_and_pybullet_forward_kinematics_agree(bullet, drake_plant):
    client, uid, links = bullet
    joints = _bullet_joints(client, uid)
    context = drake_plant.CreateDefaultContext()
    rng = np.random.default_rng(20150526)
    for k in range(60):
        q = _random_configuration(rng, torso=(0.0, 0.1, 0.25, 0.33)[k % 4])
        _set_joints(drake_plant, context, q)
        for name, value in q.items():
            pb.resetJointState(uid, joints[name][0], value, physicsClientId=client)
        for link in (rm.TOOL_FRAME, *rm.FINGER_LINKS, "r_wrist_flex_link"):
            state = pb.getLinkState(uid, links[link], computeForwardKinematics=True,
                                    physicsClientId=client)
            p_bullet = np.array(state[4])  # URDF link frame, not the COM frame (index 0)
            R_bullet = np.reshape(pb.getMatrixFromQuaternion(state[5]), (3, 3))
            X = drake_plant.EvalBodyPoseInWorld(context, drake_plant.GetBodyByName(link))
            np.testing.assert_allclose(p_bullet, X.translation(), atol=1e-6, err_msg=link)
            np.testing.assert_allclose(R_bullet, X.rotation().matrix(), atol=1e-6, err_msg=link)


def test_variants_share_identical_kinematics():
    roots = {v: _root(v) for v in rm.VARIANTS}

    def kinematic(root: ET.Element) -> list[bytes]:
        parts = [*root.iter("joint"), *root.iter("transmission")]
        parts += [link.find("inertial") for link in root.iter("link")]
        parts += [el for el in root if "collision_filter_group" in el.tag]
        return [ET.tostring(el) for el in parts]

    reference = kinematic(roots["capsules"])
    assert len([el for el in roots["capsules"] if el.tag == "joint"]) == len(rm.JOINTS)
    for variant in rm.VARIANTS[1:]:
        assert kinematic(roots[variant]) == reference, variant
        assert [el.get("name") for el in roots[variant].iter("link")] == list(LINKS)


# --- gripper -----------------------------------------------------------------------------------


@given(st.floats(0.0, rm.GRIPPER_MAX_OPENING))
def test_finger_position_round_trip(opening):
    q = rm.finger_joint_position(opening)
    assert 0.0 <= q <= Q_FINGER_MAX
    assert rm.gripper_opening(q) == pytest.approx(opening, abs=1e-15)


@pytest.mark.parametrize("opening", [-1e-9, 0.0900001, 1.0, math.nan, math.inf])
def test_finger_position_rejects_out_of_range(opening):
    with pytest.raises(ValueError):
        rm.finger_joint_position(opening)


def test_pads_centre_the_tool_frame():
    """With the fingers at q, the pads' inner faces are at y = +-q around the tool frame."""
    plant = MultibodyPlant(0.0)
    _add_arm(plant, "evaluation")
    plant.Finalize()
    context = plant.CreateDefaultContext()
    q = rm.finger_joint_position(0.06)
    _set_joints(plant, context, dict.fromkeys(rm.FINGER_JOINTS, q))
    X_WTool = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(rm.TOOL_FRAME))
    root = _root("evaluation")
    for sign, link in zip((1, -1), rm.FINGER_LINKS, strict=True):
        pad = next(c for c in root.find(f"link[@name='{link}']").iter("collision")
                   if c.find("geometry/box").get("size") == "0.036 0.0085 0.022")
        p_FP = np.fromstring(pad.find("origin").get("xyz"), sep=" ")
        X_WF = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(link))
        p_TP = X_WTool.inverse() @ (X_WF @ p_FP)  # pad centre in the tool frame
        np.testing.assert_allclose(p_TP, [rm.PAD_CENTER_X - 0.18, sign * (q + 0.00425), 0],
                                   atol=1e-12)


# --- geometry ----------------------------------------------------------------------------------


def _shapes(root: ET.Element, link: str, tag: str = "collision"):
    """(kind, dims, X_LG) of each collision/visual of a link, dims as in URDF."""
    for element in root.find(f"link[@name='{link}']").iter(tag):
        origin = element.find("origin")
        X = RigidTransform(RollPitchYaw(np.fromstring(origin.get("rpy"), sep=" ")),
                           np.fromstring(origin.get("xyz"), sep=" "))
        geometry = element.find("geometry")[0]
        yield geometry.tag, {k: np.fromstring(v, sep=" ") for k, v in geometry.attrib.items()}, X


def _outline_points(kind, dims, X) -> np.ndarray:
    """Corner points (box) or rim points (cylinder) of a shape, in the link frame."""
    if kind == "box":
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1)
        local = 0.5 * dims["size"][:, None] * signs
    else:
        assert kind == "cylinder"
        angle = np.linspace(0, 2 * np.pi, 48, endpoint=False)
        r, h = dims["radius"][0], dims["length"][0]
        local = np.hstack([np.vstack([r * np.cos(angle), r * np.sin(angle), np.full(48, z)])
                           for z in (-h / 2, h / 2)])
    return (X @ local).T


def _capsule_segment(dims, X) -> tuple[np.ndarray, np.ndarray, float]:
    half = dims["length"][0] / 2
    return X @ np.array([0, 0, -half]), X @ np.array([0, 0, half]), dims["radius"][0]


def _distance_outside_capsule(p, capsule) -> float:
    a, b, r = capsule
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * (b - a))) - r)


ARM_PROXY_LINKS = ("r_shoulder_pan_link", "r_shoulder_lift_link", "r_upper_arm_roll_link",
                   "r_elbow_flex_link", "r_forearm_roll_link", "r_wrist_flex_link",
                   "r_wrist_roll_link", rm.PALM_LINK)


@pytest.mark.parametrize("link", [*ARM_PROXY_LINKS, *rm.FINGER_LINKS])
def test_capsules_enclose_the_evaluation_outline(link):
    """The planning proxy covers the evaluation geometry; finger capsules keep their inner
    surface on the pad face (no intrusion into the grasp), so only pad corners stick out."""
    capsules = [_capsule_segment(d, X) for kind, d, X in _shapes(_root("capsules"), link)]
    assert capsules and all(len(c) == 3 for c in capsules)
    kinds = {kind for kind, *_ in _shapes(_root("capsules"), link)}
    assert kinds == {"capsule"}
    worst = max(min(_distance_outside_capsule(p, c) for c in capsules)
                for shape in _shapes(_root("evaluation"), link)
                for p in _outline_points(*shape))
    assert worst <= (0.005 if link in rm.FINGER_LINKS else 1e-9), worst


def test_sphere_gripper_proxy():
    root = _root("sphere_gripper")
    palm = list(_shapes(root, rm.PALM_LINK))
    assert len(palm) == 1 and palm[0][0] == "sphere"
    _, dims, X_PS = palm[0]
    for link in rm.FINGER_LINKS:
        assert not list(_shapes(root, link)), link
        assert list(_shapes(root, link, "visual")), link
    # The sphere encloses palm and fingers of both other variants at full opening.
    centre, radius = X_PS.translation(), dims["radius"][0]
    assert radius == rm.GRIPPER_SPHERE_RADIUS
    finger_offsets = {rm.FINGER_LINKS[0]: Q_FINGER_MAX, rm.FINGER_LINKS[1]: -Q_FINGER_MAX}
    for variant in ("capsules", "evaluation"):
        for link in (rm.PALM_LINK, *rm.FINGER_LINKS):
            offset = np.array([rm.FINGER_JOINT_X, finger_offsets.get(link, 0.0), 0.0])
            if link == rm.PALM_LINK:
                offset[:] = 0.0
            for kind, d, X in _shapes(_root(variant), link):
                if kind == "capsule":
                    a, b, r = _capsule_segment(d, X)
                    farthest = max(np.linalg.norm(a + offset - centre),
                                   np.linalg.norm(b + offset - centre)) + r
                else:
                    farthest = max(np.linalg.norm(_outline_points(kind, d, X) + offset - centre,
                                                  axis=1))
                assert farthest <= radius, (variant, link, farthest)


def test_evaluation_has_no_capsule_and_every_arm_link_has_geometry():
    root = _root("evaluation")
    assert not list(root.iter("capsule"))
    assert not list(root.iter("sphere"))
    for link in (*ARM_PROXY_LINKS, *rm.FINGER_LINKS, "base_link", "torso_lift_link"):
        for variant in ("capsules", "evaluation"):
            assert list(_shapes(_root(variant), link)), (variant, link)
            assert list(_shapes(_root(variant), link, "visual")), (variant, link)


@pytest.mark.parametrize("q_finger", [0.0, Q_FINGER_MAX])
def test_no_self_collision_in_the_home_configuration(variant, q_finger):
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    _add_arm(plant, variant)
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    home = dict.fromkeys(MOVABLE, 0.0) | {rm.TORSO_JOINT: 0.1}
    _set_joints(plant, plant_context, home | dict.fromkeys(rm.FINGER_JOINTS, q_finger))
    query = scene_graph.get_query_output_port().Eval(
        scene_graph.GetMyContextFromRoot(context))
    inspector = query.inspector()
    pairs = [(inspector.GetName(p.id_A), inspector.GetName(p.id_B))
             for p in query.ComputePointPairPenetration()]
    assert pairs == []
