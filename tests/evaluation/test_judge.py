"""Evaluation in Bullet (Sec. III): the world, the replay, the outcome classes, the scene score.

The scenario tests use hand-made scenes and hand-written trajectories: the tool frame follows
straight segments between a few (x, y) waypoints at a fixed height with the gripper horizontal
and facing +x (Drake IK on the planning world every centimetre, linear in joint space between).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest

from drake_clutter.cli import main
from drake_clutter.common.config import ConfigError
from drake_clutter.evaluation.judge import evaluate, evaluate_candidates, plan_limit_violation
from drake_clutter.evaluation.outcome import OUTCOME_KINDS, Outcome, classify, scene_score
from drake_clutter.evaluation.robust import perturbed_scene
from drake_clutter.robot import pr2
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.grading import off_the_board, target_zone_reason, tilt_angle, zone_extent
from drake_clutter.scene.scenes import (
    RobotPlacement,
    Scene,
    save_scene,
    validate_scene,
)
from drake_clutter.testing.handmade import (
    BOOKSHELF,
    CONFIG,
    FRIDGE,
    NOMINAL_ARM,
    ROBOT,
    make_box,
    make_scene,
    make_target,
    scripted_reach,
)
from drake_clutter.trajectory import Candidate, Trajectory, save_plan
from drake_clutter.worlds import bullet_world as bw
from drake_clutter.worlds.drake_world import build_planning_world

# ----------------------------------------------------------------------------- hand-made cases


@pytest.fixture(scope="module")
def clean_reach():
    scene = make_scene("clean_reach", BOOKSHELF, [make_target((0.58, 0.0)),
                                              make_box("far", (0.06, 0.06, 0.12), (0.7, 0.3))])
    return scene, scripted_reach(scene, [(0.45, 0.0), (0.58, 0.0)])


@pytest.fixture(scope="module")
def clean_outcome(clean_reach):
    return evaluate(*clean_reach, CONFIG, lift=True)


def test_clean_reach_to_isolated_target_is_success(clean_outcome):
    outcome = clean_outcome
    assert outcome.kind == "success", outcome.reason
    assert outcome.grasped and outcome.settled
    assert outcome.tracking_error < 1e-3
    assert max(b.displacement for b in outcome.boxes) < 1e-3  # nothing touched, nothing crept
    assert outcome.forces["arm_box"] == 0.0 and outcome.forces["arm_static"] == 0.0
    p_GT = np.array(outcome.grasp.p_GT)
    assert np.abs(p_GT[:2]).max() < 2e-3  # the tool frame ends on the target's axis


def test_lift_takes_the_target_away_and_never_changes_the_outcome(clean_outcome):
    lift = clean_outcome.lift
    assert lift is not None and lift.lifted and lift.in_hand
    assert lift.tool_rise == pytest.approx(CONFIG.lift_height, abs=3e-3)
    assert lift.target_rise == pytest.approx(CONFIG.lift_height, abs=1e-2)
    assert lift.others_lifted == ()
    assert clean_outcome.kind == "success"


def test_same_input_same_outcome_even_after_other_bullet_worlds(clean_reach, clean_outcome):
    scene, trajectory = clean_reach
    # A foreign client changes process-global Bullet settings between the two evaluations.
    other = pb.connect(pb.DIRECT)
    pb.setPhysicsEngineParameter(contactBreakingThreshold=0.001, numSolverIterations=3,
                                 physicsClientId=other)
    pb.disconnect(other)
    again = evaluate(scene, trajectory, CONFIG, lift=True)
    first, second = clean_outcome.to_data(), again.to_data()
    first.pop("wall_time"), second.pop("wall_time")
    assert first == second


def test_outcome_is_json_serialisable(clean_outcome):
    data = json.loads(json.dumps(clean_outcome.to_data()))
    assert data["kind"] == "success" and data["lift"]["lifted"] is True
    assert {b["name"] for b in data["boxes"]} == {"target", "far"}
    assert Outcome.from_data(data) == clean_outcome
    with pytest.raises(ValueError, match="unknown outcome kind"):
        Outcome.from_data({**data, "kind": "won"})


def test_reach_that_stops_short_is_failure_to_grasp(clean_reach):
    scene, _ = clean_reach
    outcome = evaluate(scene, scripted_reach(scene, [(0.45, 0.0), (0.50, 0.0)]), CONFIG,
                       lift=True)
    assert outcome.kind == "failure_to_grasp"
    assert "ahead of the pad zone" in outcome.reason
    assert not outcome.lift.lifted and outcome.lift.target_rise < 1e-3


def test_other_box_between_the_fingers_is_failure_to_grasp():
    scene = make_scene("two_in_hand", BOOKSHELF, [make_target((0.6, -0.015), (0.05, 0.04, 0.15)),
                                              make_box("thin", (0.05, 0.02, 0.12), (0.6, 0.025))])
    outcome = evaluate(scene, scripted_reach(scene, [(0.45, 0.0), (0.6, 0.0)]), CONFIG)
    assert outcome.kind == "failure_to_grasp", outcome.reason
    assert outcome.grasp.intruders == ("thin",)
    assert "another box is in the gripper: thin" in outcome.reason
    # The target alone would have been grasped: the zone test passes, the intruder fails it.
    assert target_zone_reason(outcome.grasp.p_GT, np.eye(3), (0.05, 0.04, 0.15),
                              outcome.grasp.opening, CONFIG) == ""


def test_sweep_that_tips_a_tall_thin_box_is_partial_success():
    # The hand sweeps +y through a 2.5 cm thin, 22 cm tall box (it topples away, towards +y,
    # and stays on the board), comes back and reaches the target on the other side.
    scene = make_scene("topple", BOOKSHELF, [make_target((0.6, -0.15)),
                                         make_box("tall", (0.08, 0.025, 0.22), (0.47, 0.0),
                                              friction=0.6)])
    path = [(0.43, -0.1), (0.47, -0.1), (0.47, 0.07), (0.47, -0.15), (0.6, -0.15)]
    outcome = evaluate(scene, scripted_reach(scene, path), CONFIG)
    assert outcome.kind == "partial_success", outcome.reason
    tall = outcome.boxes[1]
    assert tall.tipped and not tall.fallen and tall.tilt > 1.2
    assert outcome.forces["arm_box"] > 0.0


def test_push_off_the_bookshelf_edge_is_objects_falling():
    scene = make_scene("push_off", BOOKSHELF, [make_target((0.6, 0.1)),
                                           make_box("edge", (0.06, 0.06, 0.10), (0.5, -0.33))])
    outcome = evaluate(scene, scripted_reach(scene, [(0.43, -0.2), (0.5, -0.2), (0.5, -0.45)]),
                       CONFIG)
    assert outcome.kind == "objects_falling", outcome.reason
    edge = outcome.boxes[1]
    assert edge.fallen and edge.final_position[2] < BOOKSHELF.top_height
    assert not outcome.grasped  # it also missed the target: falling takes precedence


def test_hand_through_a_refrigerator_wall_is_kinematic_failure():
    scene = make_scene("through_wall", FRIDGE, [make_target((0.6, 0.1))])
    trajectory = scripted_reach(scene, [(0.43, -0.1), (0.5, -0.1), (0.5, -0.35)])
    outcome = evaluate(scene, trajectory, CONFIG, lift=True)
    assert outcome.kind == "kinematic_failure", outcome.reason
    assert "static geometry" in outcome.reason and "finger" in outcome.reason
    # The simulation stops there ("cannot be simulated to completion"), and no lift is tried.
    assert outcome.simulated_time < trajectory.duration and not outcome.settled
    assert outcome.lift is None


def test_box_pressed_into_the_back_wall_is_kinematic_failure():
    # A box wider than the open gripper, shoved into the fridge's back wall by the fingertips.
    scene = make_scene("press", FRIDGE, [make_target((0.6, 0.15)),
                                     make_box("block", (0.06, 0.12, 0.10), (0.72, -0.1), 500.0)])
    outcome = evaluate(scene, scripted_reach(scene, [(0.43, -0.1), (0.76, -0.1)]), CONFIG)
    assert outcome.kind == "kinematic_failure", outcome.reason
    assert "box 'block' pushed into static geometry" in outcome.reason
    assert outcome.forces["box_static_excess_mean"] > CONFIG.max_static_force


def test_an_arm_that_cannot_follow_is_kinematic_failure(clean_reach):
    # With motors as weak as 5 N m the arm sags under gravity: the lag must be caught.
    weak = replace(CONFIG, arm_max_force=5.0)
    outcome = evaluate(*clean_reach, weak)
    assert outcome.kind == "kinematic_failure", outcome.reason
    assert "cannot follow the trajectory" in outcome.reason
    assert outcome.tracking_error > CONFIG.max_tracking_error


def test_an_arm_at_its_speed_limits_in_free_space_follows_the_plan():
    """Every arm joint swings at up to 0.9 of the PR2's speed limit (1 s sine, two periods,
    knots every 50 ms) with the robot 1 m further back than ROBOT, out of reach of the shelf
    and every box: no kinematic failure, and the largest lag far under the limit."""
    far = replace(ROBOT, base_pose=(-1.0, *ROBOT.base_pose[1:]))
    scene = validate_scene(Scene("free_space", BOOKSHELF, far, "target",
                                 (make_target((0.7, 0.3)),)))
    centre = np.array([-0.8, 0.4, -1.5, -1.2, 0.0, -1.0, 0.0])  # rad, inside every limit
    speed = 0.9 * np.array([pr2.velocity_limits()[j] for j in pr2.ARM_JOINTS])  # rad/s
    period, times = 1.0, np.arange(0.0, 2.0 + 1e-9, 0.05)
    phase = np.sin(2 * np.pi * times / period)[:, None]
    q = np.hstack([centre + speed * period / (2 * np.pi) * phase,
                   np.full((len(times), 1), pr2.GRIPPER_MAX_OPENING)])
    trajectory = Trajectory(times, q)
    assert plan_limit_violation(trajectory, CONFIG) == ""
    peak = np.max(np.abs(np.diff(q[:, :7], axis=0)) / np.diff(times)[:, None] / speed * 0.9)
    assert peak > 0.85  # the knots do reach the speed limits
    outcome = evaluate(scene, trajectory, CONFIG)
    assert outcome.kind == "failure_to_grasp", outcome.reason
    assert outcome.tracking_error < 0.1 * CONFIG.max_tracking_error, outcome.tracking_error


def test_plan_beyond_the_velocity_limits_fails_without_simulating(clean_reach):
    scene, trajectory = clean_reach
    fast = Trajectory(trajectory.times / 50.0, trajectory.q)
    outcome = evaluate(scene, fast, CONFIG)
    assert outcome.kind == "kinematic_failure"
    assert "rad/s limit" in outcome.reason and outcome.simulated_time == 0.0


def test_candidates_without_trajectory_are_planner_failures(clean_reach):
    scene, trajectory = clean_reach
    candidates = [Candidate(0.0, "ik_failed", "no IK solution"),
                  Candidate(0.1, "ok", trajectory=trajectory)]
    outcomes = evaluate_candidates(scene, candidates, CONFIG)
    assert [o.kind for o in outcomes] == ["planner_failure", "success"]
    assert outcomes[0].reason == "ik_failed: no IK solution"
    assert scene_score(o.kind for o in outcomes) == "success"


@pytest.mark.slow
@pytest.mark.parametrize("kind,objects", [("bookshelf", 25), ("fridge", 16)])
def test_straight_reaches_into_dense_generated_scenes(kind, objects):
    # Behaviour on real scenes: straight reaches at the target's mid-height from the front edge
    # into the densest clutter levels give valid, reproducible, JSON-round-tripping outcomes.
    kinds = []
    for seed in range(4):
        scene = generate_scene(kind, objects, seed)
        target = scene.target_box
        z = scene.shelf.top_height + target.size[2] / 2
        try:
            plan = scripted_reach(scene, [(scene.shelf.front_x + 0.03, target.pose[1]),
                                          target.pose[:2]], z=z, step=0.03)
        except AssertionError:
            continue  # no IK solution for this straight line
        outcome = evaluate(scene, plan, CONFIG)
        assert outcome.kind in OUTCOME_KINDS[:5] and len(outcome.boxes) == objects
        assert outcome.simulated_time <= plan.duration + CONFIG.settle_time_cap + 0.05
        again = evaluate(scene, plan, CONFIG)
        assert replace(again, wall_time=0.0) == replace(outcome, wall_time=0.0)
        assert Outcome.from_data(json.loads(json.dumps(outcome.to_data()))) == outcome
        kinds.append(outcome.kind)
    assert len(kinds) >= 2, "too few scenes with an IK solution to say anything"


# ----------------------------------------------------------------------------- pure parts


def test_precedence_of_the_outcome_classes():
    assert classify("", [], "", []) == ("success", "grasped; every obstacle upright on the shelf")
    assert classify("", [], "", ["a"])[0] == "partial_success"
    assert classify("", [], "missed", ["a"])[0] == "failure_to_grasp"
    assert classify("", ["b"], "missed", ["a"])[0] == "objects_falling"
    assert classify("", ["b"], "", [])[0] == "objects_falling"
    assert classify("stuck", ["b"], "missed", ["a"]) == ("kinematic_failure", "stuck")


def test_scene_score_follows_sec_vi_b():
    assert scene_score(["failure_to_grasp", "success", "partial_success"]) == "success"
    assert scene_score(["kinematic_failure", "partial_success"]) == "partial_success"
    assert scene_score(["objects_falling", "planner_failure"]) == "failure"
    assert scene_score([]) == "failure"
    with pytest.raises(ValueError, match="unknown outcome kinds"):
        scene_score(["won"])


def test_pre_grasp_zone_known_answers():
    size = (0.05, 0.05, 0.15)
    centre, half = zone_extent(0.09, CONFIG)
    pad_x0 = pr2.PAD_CENTER_X - pr2.PAD_SIZE[0] / 2 - pr2.TOOL_OFFSET
    assert centre[0] - half[0] == pytest.approx(pad_x0 - CONFIG.zone_margin)
    assert half[1] == pytest.approx(0.045) and half[2] == pytest.approx(0.011)
    assert target_zone_reason((0.0, 0.0, 0.0), np.eye(3), size, 0.09, CONFIG) == ""
    assert "ahead of" in target_zone_reason((0.05, 0, 0), np.eye(3), size, 0.09, CONFIG)
    assert "behind" in target_zone_reason((-0.07, 0, 0), np.eye(3), size, 0.09, CONFIG)
    assert "does not fit" in target_zone_reason((0, 0.03, 0), np.eye(3), size, 0.09, CONFIG)
    assert "does not fit" in target_zone_reason((0, 0, 0), np.eye(3), size, 0.04, CONFIG)
    assert "not level" in target_zone_reason((0, 0, 0.07), np.eye(3), size, 0.09, CONFIG)
    # A gripper rolled by 90 deg about its approach axis sees the box's height across the gap.
    roll = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    assert "does not fit" in target_zone_reason((0, 0, 0), roll, size, 0.09, CONFIG)


def test_tilt_and_off_board_known_answers():
    c, s = math.cos(0.5), math.sin(0.5)
    assert tilt_angle(np.array([[1, 0, 0], [0, c, -s], [0, s, c]])) == pytest.approx(0.5)
    assert tilt_angle(np.eye(3)) == 0.0
    p = np.array([[0.6, 0.0, 0.8], [0.81, 0.0, 0.8], [0.6, -0.41, 0.8], [0.6, 0.0, 0.1]])
    assert off_the_board(validate_scene(Scene("s", BOOKSHELF, ROBOT, "t", (
        make_box("t", (0.05, 0.05, 0.1), (0.6, 0.0)),))), p).tolist() == [False, True, True, True]


def test_plan_limit_checks():
    q = np.tile(np.r_[NOMINAL_ARM, 0.09], (2, 1))
    ok = Trajectory([0.0, 1.0], q)
    assert plan_limit_violation(ok, CONFIG) == ""
    q_bad = q.copy()
    q_bad[1, 3] = 0.2  # elbow flex above its upper limit 0
    assert "r_elbow_flex_joint" in plan_limit_violation(Trajectory([0, 10.0], q_bad), CONFIG)
    q_wide = q.copy()
    q_wide[1, 7] = 0.12
    assert "gripper opening" in plan_limit_violation(Trajectory([0, 1.0], q_wide), CONFIG)
    q_fast = q.copy()
    q_fast[1, 0] += 0.5  # 0.5 rad in 0.1 s = 5 rad/s > 2.088 rad/s
    assert "rad/s limit" in plan_limit_violation(Trajectory([0, 0.1], q_fast), CONFIG)
    lenient = replace(CONFIG, velocity_limit_factor=3.0)
    assert plan_limit_violation(Trajectory([0, 0.1], q_fast), lenient) == ""
    with pytest.raises(ValueError, match="trajectory joints"):
        plan_limit_violation(Trajectory([0, 1.0], q, tuple("abcdefgh")), CONFIG)


# ----------------------------------------------------------------------------- the Bullet world


@pytest.fixture(scope="module")
def dense_world():
    with bw.build_bullet_world(generate_scene("fridge", 16, seed=3), CONFIG) as world:
        yield world


def test_bullet_world_matches_the_scene(dense_world):
    world, scene = dense_world, dense_world.scene
    client = world.client
    p, R = bw.box_poses(world)
    for i, box in enumerate(scene.boxes):
        info = pb.getDynamicsInfo(world.boxes[i], -1, physicsClientId=client)
        assert info[0] == pytest.approx(box.mass) and info[1] == pytest.approx(box.friction)
        low, high = pb.getAABB(world.boxes[i], physicsClientId=client)
        c, s = abs(math.cos(box.pose[2])), abs(math.sin(box.pose[2]))
        sx, sy, sz = box.size
        extent = [sx * c + sy * s, sx * s + sy * c, sz]
        assert np.allclose(np.subtract(high, low), extent, atol=3e-3)  # AABB has Bullet's margin
        assert np.allclose(p[i], [box.pose[0], box.pose[1], scene.box_center_z(box)], atol=1e-9)
        assert math.atan2(R[i][1, 0], R[i][0, 0]) == pytest.approx(box.pose[2], abs=1e-9)
    # The shelf spans the board and, for the fridge, walls and ceiling up to height + thickness.
    low, high = pb.getAABB(world.shelf, physicsClientId=client)
    shelf = scene.shelf
    top = shelf.top_height + shelf.walls.height + shelf.walls.thickness
    expected_low = [shelf.center_xy[0] - shelf.depth / 2, shelf.center_xy[1] - shelf.width / 2,
                    shelf.top_height - shelf.thickness]
    expected_high = [shelf.center_xy[0] + shelf.depth / 2, shelf.center_xy[1] + shelf.width / 2,
                     top]
    assert np.allclose(low, expected_low, atol=3e-3) and np.allclose(high, expected_high,
                                                                     atol=3e-3)
    assert bw.joint_positions(world)[0] == pytest.approx(scene.robot.torso_height)


def test_bullet_arm_is_placed_like_the_drake_arm():
    scene = replace(generate_scene("bookshelf", 1, seed=5),
                    robot=RobotPlacement(base_pose=(0.05, 0.15, 0.3), torso_height=0.25))
    drake_world = build_planning_world(scene, "evaluation")
    context = drake_world.plant.CreateDefaultContext()
    q_robot = np.r_[NOMINAL_ARM, 0.03, 0.03]
    drake_world.set_robot_positions(context, q_robot)
    X_WG = drake_world.tool_frame.CalcPoseInWorld(context)
    with bw.build_bullet_world(scene, CONFIG) as world:
        bw.reset_robot(world, bw.motor_positions(world, q_robot))
        p_WG, R_WG = bw.tool_pose(world)
    assert np.allclose(p_WG, X_WG.translation(), atol=1e-9)
    assert np.allclose(R_WG, X_WG.rotation().matrix(), atol=1e-9)


def test_tool_jacobian_matches_finite_differences():
    # Central differences with h = 1e-3: pybullet reports link poses in single precision
    # (~6e-8 m), which a smaller step would amplify; the truncation error is ~h^2.
    scene = generate_scene("bookshelf", 1, seed=5)
    h = 1e-3
    with bw.build_bullet_world(scene, CONFIG) as world:
        q = bw.motor_positions(world, np.r_[NOMINAL_ARM, 0.045, 0.045])
        J = bw.tool_jacobian(world, q)
        numeric = np.zeros((6, 7))
        for j in range(7):
            poses = []
            for sign in (1.0, -1.0):
                dq = q.copy()
                dq[1 + j] += sign * h
                bw.reset_robot(world, dq)
                poses.append(bw.tool_pose(world))
            (p1, R1), (p0, R0) = poses
            skew = (R1 @ R0.T - R0 @ R1.T) / (4 * h)  # ~ [w]x
            numeric[:, j] = np.r_[(p1 - p0) / (2 * h), skew[2, 1], skew[0, 2], skew[1, 0]]
    assert np.abs(J - numeric).max() < 2e-4
    assert np.abs(J).max() > 0.1  # not trivially zero


def test_zone_probe_measures_penetration(dense_world):
    world = dense_world
    p, _ = bw.box_poses(world)
    box = world.scene.boxes[0]
    # A 2 cm cube whose centre sits 1 cm inside the box's +x face reaches 2 cm deep.
    R = np.array(pb.getMatrixFromQuaternion(pb.getQuaternionFromEuler([0, 0, box.pose[2]])))
    R = R.reshape(3, 3)
    face = p[0] + R @ [box.size[0] / 2 - 0.01, 0, 0]
    depth = bw.region_penetrations(world, [0.01] * 3, face, R, [world.boxes[0]])[0]
    assert depth == pytest.approx(0.02, abs=1e-4)
    far = bw.region_penetrations(world, [0.01] * 3, p[0] + [0, 0, 1.0], np.eye(3),
                                 [world.boxes[0]])
    assert far == [0.0]
    assert pb.getNumBodies(physicsClientId=world.client) == 3 + len(world.boxes)  # probe gone


def test_resting_boxes_stay_put_and_press_nothing():
    scene = generate_scene("bookshelf", 25, seed=1)
    with bw.build_bullet_world(scene, CONFIG) as world:
        p0, _ = bw.box_poses(world)
        weights = world.box_masses * bw.GRAVITY
        q_park = bw.motor_positions(world, np.r_[-1.9, 0.2, 0.0, -1.9, 0.0, -0.6, 0.0, 0.0, 0.0])
        bw.reset_robot(world, q_park)
        forces = bw.motor_forces(CONFIG)
        excess = []
        for _ in range(60):  # 1 s
            bw.hold(world, q_park, forces, CONFIG.monitor_interval * CONFIG.sim_dt)
            bw.step(world, CONFIG.monitor_interval)
            excess.append(np.abs(bw.contact_sample(world).box_static - weights).max())
        p1, R1 = bw.box_poses(world)
        speeds, spins = bw.box_speeds(world)
    assert np.abs(p1 - p0).max() < 1e-3
    assert tilt_angle(R1).max() < 1e-2
    assert speeds.max() < CONFIG.rest_speed and spins.max() < CONFIG.rest_angular_speed
    assert max(excess[10:]) < 0.1 * CONFIG.max_static_force


# ----------------------------------------------------------------------------- command line


def test_cli_evaluate_writes_outcomes_and_prints_a_table(tmp_path, capsys, clean_reach):
    scene, trajectory = clean_reach
    scene_file = save_scene(scene, tmp_path / "scene.yaml")
    plan = save_plan(tmp_path / "plan.json", scene.name,
                     [Candidate(-0.2, "ik_failed", "unreachable"),
                      Candidate(0.0, "ok", trajectory=trajectory)])
    out = tmp_path / "outcome.json"
    assert main(["evaluate", str(scene_file), str(plan), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "planner_failure" in printed and "success" in printed
    assert "scene score: success" in printed
    doc = json.loads(out.read_text())
    assert doc["scene_score"] == "success"
    assert [c["outcome"]["kind"] for c in doc["candidates"]] == ["planner_failure", "success"]


def test_cli_evaluate_rejects_a_plan_for_another_scene(tmp_path, capsys, clean_reach):
    scene, trajectory = clean_reach
    scene_file = save_scene(scene, tmp_path / "scene.yaml")
    plan = save_plan(tmp_path / "plan.json", "some_other_scene",
                     [Candidate(0.0, "ok", trajectory=trajectory)])
    # A fresh process: importing pybullet must not add its banner to the one-line error.
    result = subprocess.run([sys.executable, "-m", "drake_clutter.cli", "evaluate",
                             str(scene_file), str(plan), "--out", str(tmp_path / "o.json")],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1, result.stderr
    assert "plan.json: scene:" in result.stderr and "some_other_scene" in result.stderr
    assert main(["evaluate", str(scene_file), str(tmp_path / "missing.json"), "--out",
                 str(tmp_path / "o.json")]) == 2
    assert "no such file" in capsys.readouterr().err


# ----------------------------------------------------------------------------- the robust judge


def test_robust_judge_keeps_the_nominal_outcome_and_is_seeded(clean_reach, clean_outcome):
    scene, trajectory = clean_reach
    robust = evaluate(scene, trajectory, CONFIG, lift=True, robust=4, seed=3)
    assert replace(robust, robust=None, wall_time=0.0) == replace(clean_outcome, wall_time=0.0)
    summary = robust.robust
    assert summary.replays == 4 and summary.kinds[0] == clean_outcome.kind
    assert summary.p_success == summary.p_success_or_partial == 1.0  # an isolated target
    assert summary.expected_grade == sum(g[0] for g in summary.grades) / 4
    again = evaluate(scene, trajectory, CONFIG, lift=True, robust=4, seed=3)
    assert again.robust == summary
    assert Outcome.from_data(json.loads(json.dumps(robust.to_data()))) == replace(
        robust, recording=None)
    assert "robust" not in clean_outcome.to_data()  # a nominal outcome's data is unchanged


def test_perturbed_worlds_are_valid_seeded_and_within_the_ranges():
    scene = generate_scene("bookshelf", 15, 2015)
    nominal = {b.name: b for b in scene.boxes}
    for k in (1, 2, 3):
        world = perturbed_scene(scene, CONFIG, k)
        validate_scene(world)
        assert world == perturbed_scene(scene, CONFIG, k)
        for box in world.boxes:
            ref = nominal[box.name]
            assert np.all(np.abs(np.subtract(box.pose[:2], ref.pose[:2]))
                          <= CONFIG.robust_position + 1e-12)
            assert abs(box.pose[2] - ref.pose[2]) <= CONFIG.robust_yaw + 1e-12
            assert abs(box.density / ref.density - 1) <= CONFIG.robust_mass + 1e-12
            assert abs(box.friction / ref.friction - 1) <= CONFIG.robust_friction + 1e-12
    assert perturbed_scene(scene, CONFIG, 1) != perturbed_scene(scene, CONFIG, 2)
    assert perturbed_scene(scene, CONFIG, 0) is scene


@pytest.mark.parametrize("change, field", [
    ({"robust_replays": 0}, "evaluation.robust_replays"),
    ({"robust_position": -0.001}, "evaluation.robust_position"),
    ({"robust_friction": 1.0}, "evaluation.robust_friction"),
    ({"robust_seed": 1.5}, "evaluation.robust_seed")])
def test_robust_settings_that_make_no_sense_name_their_field(clean_reach, change, field):
    with pytest.raises(ConfigError) as err:
        evaluate(*clean_reach, replace(CONFIG, **change))
    assert err.value.field == field


def test_cli_evaluate_robust_writes_the_distribution_and_rejects_bad_input(tmp_path, capsys,
                                                                          clean_reach):
    scene, trajectory = clean_reach
    scene_file = save_scene(scene, tmp_path / "scene.yaml")
    plan = save_plan(tmp_path / "plan.json", scene.name,
                     [Candidate(0.0, "ok", trajectory=trajectory)])
    out = tmp_path / "outcome.json"
    assert main(["evaluate", str(scene_file), str(plan), "--robust", "3", "--seed", "7",
                 "--out", str(out)]) == 0
    assert "P(s)" in capsys.readouterr().out
    doc = json.loads(out.read_text())
    robust = doc["candidates"][0]["outcome"]["robust"]
    assert robust["seed"] == 7 and len(robust["kinds"]) == 3
    assert doc["scene_p_success"] == robust["p_success"]
    for bad, field in ((["--robust", "0"], "--robust"), (["--seed", "-1"], "--seed"),
                       (["--set", "evaluation.robust_mass=-0.1"], "evaluation.robust_mass")):
        missing = tmp_path / "never.json"
        assert main(["evaluate", str(scene_file), str(plan), *bad, "--out", str(missing)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and field in err, err
        assert not missing.exists()
