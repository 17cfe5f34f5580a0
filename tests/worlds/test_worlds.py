"""Drake worlds: planning world and the smooth-contact dynamics phi (built and stepped)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.plant import DiscreteContactApproximation

from drake_clutter.common.config import WorldConfig
from drake_clutter.robot import pr2
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.scenes import load_shipped_scene
from drake_clutter.scene.shelf import default_shelves, shelf_sdf
from drake_clutter.worlds.drake_world import (
    ROBOT_JOINTS,
    build_dynamics_world,
    build_planning_world,
    new_dynamics_context,
    park_positions,
    set_desired_robot_state,
    step,
)


@pytest.fixture(scope="module")
def dense_scene():
    return generate_scene("bookshelf", 25, seed=0)


def test_a_deep_board_changes_only_the_boards_collision_box():
    """``board_depth`` gives the board's collision box that depth below the top (the top face
    stays at S's origin); its visual and the walls keep their sizes."""
    import xml.etree.ElementTree as ET

    shelf = default_shelves()["fridge"]

    def boxes(text):
        link = ET.fromstring(text).find("model/link")
        return {(e.tag, e.get("name")): (np.array(e.find("pose").text.split(), float)[:3],
                                         np.array(e.find("geometry/box/size").text.split(),
                                                  float))
                for e in link if e.tag in ("collision", "visual")}

    thin, deep = boxes(shelf_sdf(shelf)), boxes(shelf_sdf(shelf, board_depth=0.1))
    (centre, size), (thin_centre, thin_size) = deep["collision", "board"], thin["collision",
                                                                               "board"]
    assert size[2] == pytest.approx(0.1) and centre[2] == pytest.approx(-0.05)
    assert centre[2] + size[2] / 2 == pytest.approx(thin_centre[2] + thin_size[2] / 2)
    np.testing.assert_allclose(size[:2], thin_size[:2])
    changed = [key for key in thin if not (np.allclose(thin[key][0], deep[key][0])
                                           and np.allclose(thin[key][1], deep[key][1]))]
    assert changed == [("collision", "board")]


def test_checked_in_shelf_sdfs_match_generator():
    for kind, shelf in default_shelves().items():
        with open(pr2.repo_root() / "sdf" / f"{kind}.sdf", encoding="utf-8") as f:
            assert f.read() == shelf_sdf(shelf), f"sdf/{kind}.sdf is stale: regenerate it"


@pytest.mark.parametrize("variant", pr2.VARIANTS)
def test_planning_world_has_arm_boxes_and_welded_torso(variant):
    scene = load_shipped_scene("fig7_cascade")
    world = build_planning_world(scene, variant)
    plant = world.plant
    assert plant.num_positions() == 9 + 7 * len(scene.boxes)  # 9 robot joints + free boxes
    assert not plant.HasJointNamed(pr2.TORSO_JOINT)
    context = plant.CreateDefaultContext()
    # The shoulder-pan axis sits at the torso height the scene asks for.
    X_WS = plant.GetFrameByName("r_shoulder_pan_link").CalcPoseInWorld(context)
    expected_z = pr2.SHOULDER_PAN_HEIGHT_AT_ZERO_TORSO + scene.robot.torso_height
    assert X_WS.translation()[2] == pytest.approx(expected_z, abs=1e-9)
    for box in scene.boxes:
        p = world.X_WBox(context, box.name).translation()
        assert p == pytest.approx([box.pose[0], box.pose[1], scene.box_center_z(box)], abs=1e-12)


def _arm_obstacle_distances(world, q_robot):
    context = world.diagram.CreateDefaultContext()
    plant_context = world.plant.GetMyMutableContextFromRoot(context)
    world.set_robot_positions(plant_context, q_robot)
    query = world.plant.get_geometry_query_input_port().Eval(plant_context)
    return query.ComputeSignedDistancePairwiseClosestPoints(max_distance=10.0)


def test_planning_world_only_reports_arm_obstacle_pairs(dense_scene):
    world = build_planning_world(dense_scene, "capsules")
    pairs = _arm_obstacle_distances(world, park_positions(world, WorldConfig()))
    inspector = world.scene_graph.model_inspector()
    robot_frames = {world.plant.GetBodyFrameIdOrThrow(i)
                    for i in world.plant.GetBodyIndices(world.robot)}
    assert pairs
    for pair in pairs:
        in_robot = [inspector.GetFrameId(g) in robot_frames for g in (pair.id_A, pair.id_B)]
        assert sum(in_robot) == 1, "only arm-vs-obstacle pairs survive the filters"


@pytest.mark.parametrize("kind", ["bookshelf", "fridge"])
def test_parked_arm_is_clear_of_shelf_and_boxes(kind):
    scene = generate_scene(kind, 10, seed=4)
    world = build_planning_world(scene, "evaluation")
    pairs = _arm_obstacle_distances(world, park_positions(world, WorldConfig()))
    assert min(p.distance for p in pairs) > 0.05


def test_dynamics_world_is_sap_with_pd_servos(dense_scene):
    world = build_dynamics_world(dense_scene)
    plant = world.plant
    assert plant.get_discrete_contact_approximation() == DiscreteContactApproximation.kSap
    assert plant.num_actuated_dofs() == len(ROBOT_JOINTS)
    assert not plant.is_gravity_enabled(world.robot)


def test_phi_with_parked_arm_keeps_boxes_still_for_one_second(dense_scene):
    config = WorldConfig()
    world = build_dynamics_world(dense_scene, config=config)
    q_park = park_positions(world, config)
    root = new_dynamics_context(world, q_park)
    plant_context = world.plant.GetMyContextFromRoot(root)
    before = {n: world.X_WBox(plant_context, n).translation() for n in world.box_names}
    step(world, root, round(1.0 / config.time_step))
    assert root.get_time() == pytest.approx(1.0)
    moved = max(np.linalg.norm(world.X_WBox(plant_context, n).translation() - before[n])
                for n in world.box_names)
    assert moved < 1e-3
    np.testing.assert_allclose(world.robot_positions(plant_context), q_park, atol=1e-6)


def test_phi_pd_servos_track_a_new_target():
    scene = generate_scene("fridge", 1, seed=0)
    config = WorldConfig()
    world = build_dynamics_world(scene, config=config)
    q_park = park_positions(world, config)
    root = new_dynamics_context(world, q_park)
    plant_context = world.plant.GetMyMutableContextFromRoot(root)
    goal = q_park + np.array([0.2, -0.1, 0.1, 0.2, 0.3, 0.2, -0.3, -0.01, -0.01])
    set_desired_robot_state(world, plant_context, goal)
    step(world, root, 100)
    np.testing.assert_allclose(world.robot_positions(plant_context), goal, atol=2e-3)


@pytest.mark.parametrize("as_bullet", [False, True])
def test_box_friction_pairs_like_the_judge(as_bullet):
    """With ``friction_as_bullet`` a box's Drake coefficient b makes Drake's pair rule with the
    shelf and the arm (1.0), 2 b S / (b + S), equal Bullet's product mu * S; without it the
    box keeps the scene's mu. The dynamics world carries that coefficient."""
    from pydrake.geometry import Role

    from drake_clutter.scene.shelf import SHELF_FRICTION
    from drake_clutter.worlds.drake_world import box_friction

    config = WorldConfig(friction_as_bullet=as_bullet)
    for mu in (0.4, 0.6, 0.8):
        b = box_friction(mu, config)
        pair = 2 * b * SHELF_FRICTION / (b + SHELF_FRICTION)
        assert pair == pytest.approx(mu * SHELF_FRICTION if as_bullet else 2 * mu / (1 + mu))
    scene = load_shipped_scene("fig5_large_small")
    world = build_dynamics_world(scene, config=config)
    inspector = world.scene_graph.model_inspector()
    box = next(b for b in scene.boxes if b.name == "target")
    body = world.plant.GetBodyByName(box.name, world.boxes)
    (geometry,) = world.plant.GetCollisionGeometriesForBody(body)
    friction = inspector.GetProperties(geometry, Role.kProximity).GetProperty(
        "material", "coulomb_friction")
    assert friction.static_friction() == pytest.approx(box_friction(box.friction, config))


def test_edge_points_cover_the_twelve_edges_at_most_spacing_apart():
    """The "edges" support spheres: the 8 corners, and along each edge evenly spread points at
    most ``spacing`` apart; every point lies on an edge (two coordinates at +-half size)."""
    from drake_clutter.worlds.drake_world import edge_points

    size = np.array([0.08, 0.06, 0.22])
    corners = edge_points(size, 0.0)
    assert len(corners) == 8
    np.testing.assert_allclose(np.abs(corners), np.tile(size / 2, (8, 1)))
    points = edge_points(size, 0.02)
    on_faces = np.isclose(np.abs(points), size / 2).sum(axis=1)
    assert np.all(on_faces >= 2)
    assert len(np.unique(points.round(9), axis=0)) == len(points)
    for axis in range(3):  # one edge along each axis: consecutive points at most 2 cm apart
        others = [a for a in range(3) if a != axis]
        edge = points[np.all(np.isclose(points[:, others], -size[others] / 2), axis=1)]
        gaps = np.diff(np.sort(edge[:, axis]))
        assert gaps.max() <= 0.02 + 1e-12 and len(edge) == int(np.ceil(size[axis] / 0.02)) + 1
