"""The baseline planner (Sec. IV): approach poses, IK, the static-hull cost and the dense check
(`clearance`), the optimisation, plan_baseline on real scenes, and the `plan` command."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import Role
from pydrake.math import RigidTransform

from drake_clutter.common.config import BaselineConfig, Config, ConfigError
from drake_clutter.planners import baseline as bl
from drake_clutter.planners import clearance as cl
from drake_clutter.planners.approach import (
    PoseIk,
    approach_angles,
    approach_poses,
    gripper_extent,
    gripper_rotation,
    ik_seeds,
    static_planning_world,
)
from drake_clutter.planners.selection import selected_index
from drake_clutter.robot.pr2 import velocity_limits
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.scenes import BoxObject, load_shipped_scene, shipped_scene_names
from drake_clutter.trajectory import TRAJECTORY_JOINTS, load_plan, spline_basis
from drake_clutter.worlds.drake_world import build_planning_world

REPO = Path(__file__).resolve().parents[2]
CONFIG = BaselineConfig()


def _target_only(scene, target_xy=None):
    """The scene with its target alone (optionally moved to ``target_xy``)."""
    target = scene.target_box
    if target_xy is not None:
        target = dataclasses.replace(target, pose=(*target_xy, target.pose[2]))
    return dataclasses.replace(scene, boxes=(target,))


@pytest.fixture(scope="module")
def bookshelf():
    return _target_only(generate_scene("bookshelf", 1, seed=0))


@pytest.fixture(scope="module")
def bookshelf_plan(bookshelf):
    return bl.plan_baseline(bookshelf, CONFIG)


@pytest.fixture(scope="module")
def world(bookshelf):
    return static_planning_world(bookshelf)


@pytest.fixture(scope="module")
def clearance(world):
    return cl.ShelfClearance(world)


# ----------------------------------------------------------------------------- independent checks


class ShelfDistances:
    """An independent arm-vs-shelf distance check: the full planning world of a scene (boxes
    included as bodies, ignored here), pairs filtered to those with a shelf geometry."""

    def __init__(self, scene):
        self.world = build_planning_world(scene, "capsules")
        self.root = self.world.diagram.CreateDefaultContext()
        self.context = self.world.plant.GetMyMutableContextFromRoot(self.root)
        inspector = self.world.scene_graph.model_inspector()
        shelf_frames = {self.world.plant.GetBodyFrameIdOrThrow(i)
                        for i in self.world.plant.GetBodyIndices(self.world.shelf)}
        self.shelf = {g for g in inspector.GetAllGeometryIds(Role.kProximity)
                      if inspector.GetFrameId(g) in shelf_frames}

    def min_distance(self, q_traj_row) -> float:
        self.world.set_robot_positions(self.context, self.world.robot_q(q_traj_row[:7],
                                                                        q_traj_row[7]))
        query = self.world.plant.get_geometry_query_input_port().Eval(self.context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(0.05)
        return min([p.distance for p in pairs if {p.id_A, p.id_B} & self.shelf] + [0.05])

    def tool_pose(self, q_traj_row):
        self.world.set_robot_positions(self.context, self.world.robot_q(q_traj_row[:7],
                                                                        q_traj_row[7]))
        return self.world.tool_frame.CalcPoseInWorld(self.context)

    def deepest_along(self, trajectory, substeps: int = 20) -> float:
        """Deepest penetration (m) over ``substeps`` samples per knot interval."""
        times = np.linspace(0.0, trajectory.duration, substeps * (trajectory.num_knots - 1) + 1)
        return max(0.0, -min(self.min_distance(row) for row in trajectory.at(times)))


def _expected_pregrasp(scene, alpha, config):
    """Pre-grasp tool pose from the paper's description, computed here from first principles."""
    target = scene.target_box
    h = max(config.grasp_height_fraction * target.size[2],
            0.045 + config.d_safe + config.pose_clearance)  # palm capsule radius 0.045 m
    x_axis = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    # "the target centred between the open fingers": the pads' centre (0.165 m ahead of the
    # palm; G, the tool frame, 0.18 m) on the target's centre, so G 1.5 cm beyond it
    pads_to_tool = 0.18 - 0.165 if config.grasp_point == "pads" else 0.0
    p = (np.array([target.pose[0], target.pose[1], scene.shelf.top_height + h])
         + pads_to_tool * x_axis)
    return p, x_axis


# ----------------------------------------------------------------------------- approach poses


def test_approach_angles_are_spread_inside_the_open_interval():
    alphas = approach_angles(CONFIG)
    assert len(alphas) == 14
    assert np.all(alphas > CONFIG.alpha_min) and np.all(alphas < CONFIG.alpha_max)
    np.testing.assert_allclose(np.diff(alphas), np.diff(alphas)[0])
    np.testing.assert_allclose(alphas, -alphas[::-1])  # symmetric about straight ahead


def test_gripper_rotation_is_horizontal_along_the_approach():
    for alpha in (-0.9, 0.0, 0.4):
        R = gripper_rotation(alpha).matrix()
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(R[:, 0], [np.cos(alpha), np.sin(alpha), 0.0], atol=1e-12)
        np.testing.assert_allclose(R[:, 2], [0.0, 0.0, 1.0], atol=1e-12)


def test_gripper_extent_of_the_capsule_proxy(world):
    extent = gripper_extent(world)
    assert extent.below == pytest.approx(0.045, abs=1e-9)  # palm capsule radius
    assert extent.ahead == pytest.approx(0.1755 + 0.016 - 0.18, abs=1e-9)  # finger cap - tool


@pytest.mark.parametrize("grasp_point", ["pads", "tool_frame"])
def test_approach_poses_follow_sec_iv(bookshelf, world, grasp_point):
    extent = gripper_extent(world)
    shelf = bookshelf.shelf
    config = dataclasses.replace(CONFIG, grasp_point=grasp_point)
    for alpha in approach_angles(config):
        poses = approach_poses(bookshelf, alpha, config, extent)
        p_pre, x_axis = _expected_pregrasp(bookshelf, alpha, config)
        np.testing.assert_allclose(poses.X_WPregrasp.translation(), p_pre, atol=1e-12)
        np.testing.assert_allclose(poses.X_WStart.rotation().matrix()[:, 0], x_axis, atol=1e-12)
        start = poses.X_WStart.translation()
        # On line l: the fingertips d_safe + clearance in front of the board's front edge...
        assert start[0] + extent.ahead == pytest.approx(
            shelf.front_x - CONFIG.d_safe - CONFIG.pose_clearance)
        # ... on the ray from the target back along the approach direction, at the same height.
        back = p_pre - start
        assert np.cross(back, x_axis) == pytest.approx(np.zeros(3), abs=1e-12)
        assert back @ x_axis > 0 and start[2] == pytest.approx(p_pre[2], abs=1e-12)


def test_grasp_height_clears_the_board_for_a_short_target(bookshelf, world):
    short = dataclasses.replace(bookshelf.target_box, size=(0.05, 0.05, 0.06))
    scene = dataclasses.replace(bookshelf, boxes=(short,))
    poses = approach_poses(scene, 0.0, CONFIG, gripper_extent(world))
    clearance = poses.height - 0.045  # palm capsule bottom above the board top
    assert clearance == pytest.approx(CONFIG.d_safe + CONFIG.pose_clearance)


def test_ik_reaches_the_pregrasp_pose_clear_of_the_shelf(bookshelf, world, clearance):
    ik = PoseIk(world, CONFIG)
    poses = approach_poses(bookshelf, -0.5, CONFIG, gripper_extent(world))
    result = ik.solve(poses.X_WPregrasp, [np.array(p) for p in CONFIG.ik_nominal_postures])
    assert result.q is not None, result.reason
    clearance.set_arm(result.q)
    X = world.tool_frame.CalcPoseInWorld(clearance.context)
    assert np.linalg.norm(X.translation() - poses.X_WPregrasp.translation()) < 2e-4
    assert min(c.distance for c in clearance.contacts(result.q, 1.0)) >= CONFIG.ik_min_distance \
        - 1e-6


def test_ik_failure_is_an_outcome_not_an_error(bookshelf, world):
    ik = PoseIk(world, CONFIG)
    far = approach_poses(bookshelf, 0.0, CONFIG, gripper_extent(world)).X_WPregrasp
    far.set_translation(far.translation() + [2.0, 0.0, 0.0])  # 2 m beyond the arm's reach
    result = ik.solve(far, [np.array(p) for p in CONFIG.ik_nominal_postures])
    assert result.q is None and "out of reach" in result.reason


# ----------------------------------------------------------------------------- costs and gradients


def _near_board_configuration(scene, world):
    """Arm angles with the palm capsule sunk 1 cm into the bookshelf board (kinematic IK)."""
    ik = PoseIk(world, CONFIG)
    poses = approach_poses(scene, 0.6, CONFIG, gripper_extent(world))
    X = RigidTransform(poses.X_WPregrasp)
    X.set_translation(X.translation() - [0.0, 0.0, poses.height - 0.035])
    result = ik.solve(X, ik_seeds(CONFIG, [], 0), clear_of_shelf=False)
    assert result.q is not None, "no kinematic solution for the test configuration"
    return result.q


def test_smooth_penetration_is_table_i_penetration_made_c1():
    d_safe = CONFIG.d_safe
    assert cl.smooth_penetration(0.0, d_safe) == (0.0, 0.0)  # d_safe apart: nothing
    for gap in (0.5 * d_safe, d_safe, 1.7 * d_safe):  # slope = finite difference
        eps = 1e-7
        numeric = (cl.smooth_penetration(gap + eps, d_safe)[0]
                   - cl.smooth_penetration(gap - eps, d_safe)[0]) / (2 * eps)
        assert cl.smooth_penetration(gap, d_safe)[1] == pytest.approx(numeric, rel=1e-5)
    # once touching, it grows one for one with the depth, as Table I's penetration
    deeper = cl.smooth_penetration(d_safe + 0.01, d_safe)[0] - cl.smooth_penetration(d_safe,
                                                                                     d_safe)[0]
    assert deeper == pytest.approx(0.01)


def test_penetration_gradient_matches_finite_differences(bookshelf, world, clearance):
    q = _near_board_configuration(bookshelf, world)
    value, grad = clearance.penetration(q, CONFIG.d_safe)
    assert value > 0, "the test configuration must be inside the margin"
    eps = 1e-6
    numeric = np.array([(clearance.penetration(q + eps * e, CONFIG.d_safe)[0]
                         - clearance.penetration(q - eps * e, CONFIG.d_safe)[0]) / (2 * eps)
                        for e in np.eye(7)])
    # ~3e-5 relative at any step 1e-7..1e-4: the accuracy of the GJK/EPA normals, not FD noise
    assert np.linalg.norm(grad - numeric) <= 1e-3 * np.linalg.norm(numeric)


def test_path_cost_gradient_matches_finite_differences(bookshelf, world, clearance):
    q_end = _near_board_configuration(bookshelf, world)
    q_start = q_end + np.array([0.3, -0.2, 0.1, 0.2, 0.0, 0.1, 0.0])
    q = cl.interpolate(q_start, q_end, 8)
    optimiser = cl.PathOptimiser(world, clearance, CONFIG)
    value, grad = optimiser.path_cost(q, 2)
    hull = cl.static_hull_cost(clearance, q, CONFIG.d_safe, 2)[0]
    assert hull > 0
    assert value == pytest.approx(CONFIG.w_static_hull * hull + CONFIG.w_vel
                                  * cl.velocity_cost(q))
    eps = 1e-6
    rng = np.random.default_rng(0)
    for _ in range(6):  # directional derivatives along random directions
        direction = rng.normal(size=q.shape)
        numeric = (optimiser.path_cost(q + eps * direction, 2)[0]
                   - optimiser.path_cost(q - eps * direction, 2)[0]) / (2 * eps)
        # Relative to the sum of the magnitudes of the terms: a directional derivative can be a
        # near-cancellation of large terms, where plain relative error measures rounding.
        scale = np.sum(np.abs(grad * direction))
        assert abs(np.sum(grad * direction) - numeric) <= 1e-3 * scale + 1e-8


def test_spline_basis_reproduces_straight_lines():
    basis = spline_basis(30, 10, 4)
    np.testing.assert_allclose(basis.sum(axis=1), 1.0)
    assert basis[0, 0] == 1.0 and basis[-1, -1] == 1.0
    line = cl.interpolate(np.zeros(7), np.arange(7.0), 30)
    mapping = cl.PathMap(basis, line[0])
    points = np.linalg.lstsq(basis[:, 1:], line - mapping.offset, rcond=None)[0]
    np.testing.assert_allclose(mapping(points.ravel()), line, atol=1e-12)


def test_optimiser_finds_the_straight_line_without_obstacle_costs(world, clearance):
    """Known answer: with w_static_hull = 0 and both ends fixed, min sum ||dq||^2 is the
    straight line in joint space, whatever the initial guess."""
    config = dataclasses.replace(CONFIG, w_static_hull=0.0, fix_last_knot=True,
                                 opt_optimality_tolerance=1e-6)
    optimiser = cl.PathOptimiser(world, clearance, config)
    q_start = np.array([-0.5, 0.3, -1.5, -1.8, 1.0, -1.0, 0.5])
    q_end = q_start + np.array([0.4, 0.2, -0.3, 0.5, 0.6, -0.4, 0.2])
    line = cl.interpolate(q_start, q_end, config.num_knots)
    bump = np.sin(np.linspace(0, np.pi, config.num_knots))[:, None] * 0.3
    clearance.set_arm(q_end)
    X_WG = world.tool_frame.CalcPoseInWorld(clearance.context)
    result = optimiser.optimise(line + bump, X_WG)
    assert result.feasible and result.solver == "snopt"
    np.testing.assert_allclose(result.q, line, atol=1e-5)


# ----------------------------------------------------------------------------- the dense check


def test_dense_check_catches_a_crossing_between_knots(bookshelf, world, clearance):
    """Two clear knots, the fingertips 5 cm over the board's front edge, one 8 cm above the
    board and one 6 cm below it: the straight joint path between them sweeps the fingers
    through the board. Knots alone miss it."""
    ik = PoseIk(world, CONFIG)
    shelf = bookshelf.shelf
    X_above = RigidTransform(gripper_rotation(0.0), [shelf.front_x + 0.05, bookshelf.target_box
                                                     .pose[1], shelf.top_height + 0.08])
    X_below = RigidTransform(X_above)
    X_below.set_translation(X_above.translation() - [0.0, 0.0, 0.14 + shelf.thickness])
    above = ik.solve(X_above, [np.array(p) for p in CONFIG.ik_nominal_postures])
    below = ik.solve(X_below, ik_seeds(CONFIG, [above.q], 0))
    assert above.q is not None and below.q is not None
    path = cl.interpolate(above.q, below.q, 2)
    knots_only = cl.dense_check(clearance, path, dataclasses.replace(CONFIG, check_substeps=1))
    assert knots_only.passed
    dense = cl.dense_check(clearance, path, CONFIG)
    assert not dense.passed and dense.depth > 0.01 and "board" in dense.where
    assert dense.samples == CONFIG.check_substeps + 1


# ----------------------------------------------------------------------------- plan_baseline


def test_target_only_scene_every_ik_feasible_angle_is_ok(bookshelf, bookshelf_plan):
    """On a scene with only the target, every IK-feasible angle ends at the pre-grasp
    pose (1 mm, 0.01 rad) and passes a dense check (here an independent one, 20 per interval)."""
    feasible = [c for c in bookshelf_plan if c.status != "ik_failed"]
    assert len(feasible) >= 6, [c.reason for c in bookshelf_plan]
    check = ShelfDistances(bookshelf)
    for c in feasible:
        assert c.status == "ok", (c.alpha, c.reason)
        p_pre, x_axis = _expected_pregrasp(bookshelf, c.alpha, CONFIG)
        X = check.tool_pose(c.trajectory.q[-1])
        assert np.linalg.norm(X.translation() - p_pre) < 1e-3
        R = X.rotation().matrix()
        assert np.arccos(np.clip(R[:, 0] @ x_axis, -1, 1)) < 0.01
        assert np.arccos(np.clip(R[:, 2] @ [0, 0, 1], -1, 1)) < 0.01
        assert check.deepest_along(c.trajectory) <= CONFIG.check_tolerance


def test_candidates_carry_a_complete_trajectory(bookshelf, bookshelf_plan):
    check = ShelfDistances(bookshelf)
    extent = gripper_extent(static_planning_world(bookshelf))
    for c in bookshelf_plan:
        assert c.planner == "baseline" and set(c.timings) >= {"ik"}
        if c.status == "ik_failed":
            assert c.trajectory is None and c.reason
            continue
        traj = c.trajectory
        assert traj.joint_names == TRAJECTORY_JOINTS
        np.testing.assert_allclose(traj.times, np.arange(CONFIG.num_knots) * CONFIG.knot_time)
        np.testing.assert_allclose(traj.q[:, 7], 0.09)  # gripper fully open
        start = approach_poses(bookshelf, c.alpha, CONFIG, extent).X_WStart
        assert np.linalg.norm(check.tool_pose(traj.q[0]).translation()
                              - start.translation()) < 1e-3
        assert {"ik", "optimisation", "check"} <= set(c.timings)
        speed = np.abs(np.diff(traj.q[:, :7], axis=0)) / CONFIG.knot_time
        limits = [velocity_limits()[name] for name in TRAJECTORY_JOINTS[:7]]
        assert np.all(speed <= np.array(limits) * CONFIG.velocity_limit_scale + 1e-6)


def test_each_candidate_stores_the_record_the_planner_built(bookshelf, bookshelf_plan):
    """Every angle's details are its `BaselineRecord`, written and read back unchanged; a
    failed IK (the target 1.5 m beyond its place) leaves the optimisation's and the check's
    fields out."""
    x, y, yaw = bookshelf.target_box.pose
    beyond = bl.plan_baseline(_target_only(bookshelf, (x + 1.5, y)), CONFIG, [0.0])
    assert beyond[0].status == "ik_failed"
    for c in bookshelf_plan + beyond:
        record = bl.BaselineRecord.from_details(c.details)
        assert record.to_details() == c.details
        assert record.height > 0 and len(record.start_xyz) == len(record.pregrasp_xyz) == 3
        if c.status == "ik_failed":
            assert set(c.details) == {"height", "start_xyz", "pregrasp_xyz"}
            assert record.score() is None
            continue
        assert record.opt_passes in (1, 2) and len(record.c_vel) == 2
        assert record.check_samples > 0 and record.max_penetration is not None
        assert record.score() >= 0.0


def test_the_optimisation_repairs_a_penetrating_straight_line(bookshelf_plan):
    """At least one angle's straight joint-space line entered the d_safe margin (or the shelf)
    and came out of the optimisation clear."""
    repaired = [c for c in bookshelf_plan if c.ok and c.details["c_static_hull"][0] > 1e-4]
    assert repaired, [c.details.get("c_static_hull") for c in bookshelf_plan]
    for c in repaired:
        before, after = c.details["c_static_hull"]
        assert after < 0.1 * before


def test_fridge_angles_crossing_a_side_wall_are_never_returned_penetrating():
    """On a refrigerator scene, an angle whose straight line crosses a side wall is
    routed around it or discarded; a returned path never penetrates (independent check)."""
    scene = _target_only(generate_scene("fridge", 1, seed=2))
    x0, _, y0, y1 = scene.shelf.interior_bounds()
    extent = gripper_extent(static_planning_world(scene))

    def crosses_a_side_wall(alpha):
        poses = approach_poses(scene, alpha, CONFIG, extent)
        a, b = poses.X_WStart.translation(), poses.X_WPregrasp.translation()
        y = a[1] + (x0 - a[0]) / (b[0] - a[0]) * (b[1] - a[1])  # at the board's front edge
        return not y0 < y < y1

    candidates = bl.plan_baseline(scene, CONFIG)
    crossing = [c for c in candidates if crosses_a_side_wall(c.alpha)]
    assert crossing and any(c.ok for c in candidates)
    check = ShelfDistances(scene)
    for c in candidates:
        if c.ok:
            assert check.deepest_along(c.trajectory) <= CONFIG.check_tolerance, c.alpha
        elif c.status == "collision_check_failed":
            assert c.details["max_penetration"] > CONFIG.check_tolerance
            assert "penetrates" in c.reason and c.trajectory is not None
        else:
            assert c.reason


def test_box_obstacles_are_ignored(bookshelf):
    """Sec. IV ignores the movable boxes: a box in the way changes nothing."""
    blocker = BoxObject("blocker", (0.08, 0.3, 0.2), (bookshelf.shelf.front_x + 0.06,
                                                      bookshelf.target_box.pose[1], 0.0),
                        500.0, 0.5)
    cluttered = dataclasses.replace(bookshelf, boxes=(*bookshelf.boxes, blocker))
    a = bl.plan_baseline(bookshelf, CONFIG, [0.85])[0]
    b = bl.plan_baseline(cluttered, CONFIG, [0.85])[0]
    assert a.ok, a.reason
    assert a.status == b.status
    np.testing.assert_allclose(a.trajectory.q, b.trajectory.q, atol=1e-9)


@pytest.mark.parametrize("field,value", [("num_angles", 0), ("alpha_max", 2.0),
                                         ("num_knots", 1), ("opt_control_points", 2)])
def test_nonsense_configuration_is_a_config_error(bookshelf, field, value):
    with pytest.raises(ConfigError) as info:
        bl.plan_baseline(bookshelf, dataclasses.replace(CONFIG, **{field: value}))
    assert f"baseline.{field}" in str(info.value)


# ----------------------------------------------------------------------------- the command


def test_the_selected_candidate_has_the_lowest_kinematic_cost():
    from drake_clutter.planners.selection import selection_score
    from drake_clutter.trajectory import Candidate, Trajectory

    def candidate(hull, vel, status="ok"):
        details = {"c_static_hull": [1.0, hull], "c_vel": [9.0, vel]}
        path = Trajectory(np.array([0.0, 0.1]), np.zeros((2, 8)))
        return Candidate(0.1, status, "", path, planner="baseline", details=details)

    config = Config()
    weights = config.baseline
    cands = [candidate(0.01, 0.1), candidate(0.0, 0.5), candidate(0.0, 0.2, "ik_failed")]
    assert selection_score("baseline", cands[0].details, config) == pytest.approx(
        weights.w_static_hull * 0.01 + weights.w_vel * 0.1)
    expected = 0 if weights.w_static_hull * 0.01 + 0.1 < 0.5 else 1
    assert selected_index(cands, config) == expected
    assert selected_index([cands[2]], config) is None  # a failed candidate is never chosen


def test_a_physics_plan_without_phi_scores_is_ranked_by_its_start():
    from drake_clutter.planners.selection import selection_score

    chosen = {"select": {"objectives": {"post": 2.0, "pre": 3.0}, "chosen": "post"},
              "start_score": 9.0}
    assert selection_score("physics", chosen) == 2.0
    staged = {"stages": {"full": {"cost_history": [5.0, 4.0]}}, "start_score": 9.0}
    assert selection_score("physics", staged) == 4.0
    assert selection_score("physics", {"stages": {}, "start_score": 9.0}) == 9.0
    assert selection_score("physics", {"stages": {}}) is None


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "drake_clutter.cli", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=300)


def test_plan_command_writes_every_angle(tmp_path):
    out = tmp_path / "plan.json"
    result = _run("plan", "fig5_large_small", "--planner", "baseline", "--angles", "3",
                  "--out", str(out))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert lines[0].split()[:2] == ["alpha", "status"] and len(lines) == 1 + 3 + 2
    scene_name, candidates, doc = load_plan(out)
    assert scene_name == "fig5_large_small" and doc["planner"] == "baseline"
    assert len(candidates) == 3
    # The candidate the baseline would execute: its lowest kinematic cost among the usable.
    usable = [i for i, c in enumerate(candidates) if c.ok]
    assert doc["selected"]["baseline"] == selected_index(candidates)
    assert doc["selected"]["baseline"] in usable
    assert lines[-2].startswith("baseline would execute: alpha")
    raw = json.loads(out.read_text())["candidates"]
    for c, data in zip(candidates, raw, strict=True):
        assert {"alpha", "status", "reason", "timings", "trajectory"} <= set(data)
        assert "ik" in c.timings
        if c.trajectory is not None:
            assert data["trajectory"]["joint_names"] == list(TRAJECTORY_JOINTS)
            assert len(data["trajectory"]["times"]) == CONFIG.num_knots
            assert "optimisation" in c.timings
        assert c.status in lines[1 + candidates.index(c)]


@pytest.mark.parametrize("args,needle", [
    (["plan", "no/such/scene.yaml", "--out", "p.json"], "no such file"),
    (["plan", "no_such_scene", "--out", "p.json"], "no shipped scene"),
    (["plan", "fig5_large_small", "--angles", "0", "--out", "p.json"], "--angles"),
    (["plan", "fig5_large_small", "--planner", "magic", "--out", "p.json"], "invalid choice"),
    (["plan", "fig5_large_small", "--set", "baseline.num_knots=1", "--out", "p.json"],
     "baseline.num_knots"),
    (["plan", "fig5_large_small", "--out", "/no/such/dir/p.json"], "--out"),
])
def test_plan_command_bad_input_is_one_line_exit_2(args, needle):
    result = _run(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
@pytest.mark.parametrize("name", shipped_scene_names())
def test_shipped_scenes_ok_candidates_are_clear_and_end_at_the_pregrasp(name):
    scene = load_shipped_scene(name)
    candidates = bl.plan_baseline(scene, CONFIG)
    assert len(candidates) == CONFIG.num_angles and any(c.ok for c in candidates)
    check = ShelfDistances(scene)
    for c in candidates:
        if not c.ok:
            continue
        p_pre, x_axis = _expected_pregrasp(scene, c.alpha, CONFIG)
        X = check.tool_pose(c.trajectory.q[-1])
        assert np.linalg.norm(X.translation() - p_pre) < 1e-3
        assert np.arccos(np.clip(X.rotation().matrix()[:, 0] @ x_axis, -1, 1)) < 0.01
        assert check.deepest_along(c.trajectory) <= CONFIG.check_tolerance, (name, c.alpha)
