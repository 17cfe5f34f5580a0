"""The recording of the Bullet replay (evaluation.evaluate(record_fps=...)) and the Meshcat
animation built from it (viz/replay.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pydrake.geometry import Meshcat

from drake_clutter.common.config import Config
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.evaluation.recording import Recorder, Recording
from drake_clutter.scene.grading import tilt_angle
from drake_clutter.testing.handmade import (
    BOOKSHELF,
    CONFIG,
    make_box,
    make_scene,
    make_target,
    scripted_reach,
)
from drake_clutter.trajectory import Candidate
from drake_clutter.viz.replay import PlanView, arrow_frames, box_states, copy_offset, record_replay
from drake_clutter.viz.views import static_html_paths

FPS = 30.0
CFG = Config()


def _rotation(q_wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = q_wxyz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@pytest.fixture(scope="module")
def topple():
    """The sweep of test_evaluation that tips a tall thin box (partial success)."""
    scene = make_scene("topple", BOOKSHELF, [make_target((0.6, -0.15)),
                                         make_box("tall", (0.08, 0.025, 0.22), (0.47, 0.0),
                                              friction=0.6)])
    path = [(0.43, -0.1), (0.47, -0.1), (0.47, 0.07), (0.47, -0.15), (0.6, -0.15)]
    trajectory = scripted_reach(scene, path)
    plain = evaluate(scene, trajectory, CONFIG)
    recorded = evaluate(scene, trajectory, CONFIG, record_fps=FPS)
    return scene, trajectory, plain, recorded


def test_recording_is_off_by_default_and_changes_nothing(topple):
    _, _, plain, recorded = topple
    assert plain.recording is None and recorded.recording is not None
    assert recorded.to_data() | {"wall_time": 0} == plain.to_data() | {"wall_time": 0}
    assert replace(recorded, wall_time=0.0) == replace(plain, wall_time=0.0)
    assert plain.kind == "partial_success"


def test_frames_at_the_rate_from_start_to_the_classified_state(topple):
    scene, trajectory, plain, recorded = topple
    rec = recorded.recording
    n = len(scene.boxes)
    assert rec.box_names == tuple(b.name for b in scene.boxes)
    assert rec.box_positions.shape == (rec.num_frames, n, 3)
    assert rec.box_quaternions.shape == (rec.num_frames, n, 4)
    assert rec.robot_q.shape == (rec.num_frames, 10)
    assert rec.times[0] == 0.0
    assert np.allclose(np.diff(rec.times[:-1]), 1.0 / FPS)
    assert 0.0 < rec.times[-1] - rec.times[-2] <= 1.0 / FPS + 1e-9
    assert rec.times[-1] == pytest.approx(plain.simulated_time)
    assert rec.num_frames == pytest.approx(plain.simulated_time * FPS, abs=2)
    np.testing.assert_allclose(rec.box_positions[-1],
                               [b.final_position for b in plain.boxes], atol=1e-12)
    assert np.allclose(np.linalg.norm(rec.box_quaternions, axis=2), 1.0)
    tilts = tilt_angle(np.array([_rotation(q) for q in rec.box_quaternions[:, 1]]))
    assert tilts[0] < 1e-3 and tilts[-1] == pytest.approx(plain.boxes[1].tilt, abs=1e-9)
    # the arm follows the plan: the first frame is the first knot
    np.testing.assert_allclose(rec.robot_q[0, 1:8], trajectory.q[0, :7], atol=1e-12)


def test_contacts_are_the_arm_pushing_the_tall_box(topple):
    _, _, plain, recorded = topple
    rec = recorded.recording
    touching = [k for k, c in enumerate(rec.contacts) if len(c)]
    assert touching, "the sweep touches the tall box"
    for k in touching:
        rows, boxes = rec.contacts[k], rec.contact_boxes[k]
        assert rows.shape == (len(boxes), 7)
        np.testing.assert_allclose(np.linalg.norm(rows[:, 3:6], axis=1), 1.0, atol=1e-6)
        assert np.all(rows[:, 6] >= 0.0)
    assert {int(i) for k in touching for i in rec.contact_boxes[k]} <= {0, 1}
    assert 1 in {int(i) for k in touching for i in rec.contact_boxes[k]}
    # the largest single contact force cannot exceed the largest summed one the judge saw
    assert 0.0 < rec.largest_contact_force() <= plain.forces["arm_box"] + 1e-9
    # while pushing, the force on the tall box points mostly along the sweep (+y) at first
    first = touching[0]
    pushes = rec.contacts[first][rec.contact_boxes[first] == 1]
    assert pushes[:, 4].mean() > 0.5


def test_recorder_rejects_a_non_positive_rate():
    with pytest.raises(ValueError, match="positive"):
        Recorder(0.0)


# ----------------------------------------------------------------------------- Meshcat replay


@pytest.fixture(scope="module")
def replay(topple):
    scene, trajectory, _, recorded = topple
    meshcat = Meshcat()
    physics = Candidate(0.1, "ok", trajectory=trajectory, planner="physics")
    baseline = Candidate(0.1, "ok", trajectory=trajectory, planner="baseline")
    summary = record_replay(scene, [PlanView("physics", physics, recorded),
                                    PlanView("baseline", baseline, None)], CFG, meshcat)
    return scene, summary, static_html_paths(meshcat.StaticHtml()), recorded


def test_replay_draws_two_copies_of_the_scene(replay):
    scene, summary, paths, recorded = replay
    assert summary.paths == ("/drake/illustration", "/drake/illustration_baseline")
    for prefix in summary.paths:
        for box in scene.boxes:
            assert f"{prefix}/boxes/{box.name}" in paths
        assert f"{prefix}/shelf/shelf_link" in paths
        assert f"{prefix}/pr2_arm/r_gripper_l_finger_link" in paths
    # the recorded view runs as long as the Bullet replay, the plan-only one as the plan
    assert summary.frames[0] == recorded.recording.num_frames
    assert summary.frames[1] == int(np.ceil(recorded.trajectory_time * CFG.viz.fps)) + 1
    assert summary.duration == pytest.approx((max(summary.frames) - 1) / CFG.viz.fps)
    np.testing.assert_allclose(copy_offset(scene, 1, CFG),
                               [0, -scene.shelf.width - CFG.viz.copy_margin, 0])


def test_replay_highlights_the_tipped_box_and_draws_forces(replay):
    _, summary, paths, _ = replay
    assert summary.highlighted == ({"tipped": 1, "fallen": 0}, {"tipped": 0, "fallen": 0})
    assert "/drake/illustration/boxes/tall/highlight_tipped" in paths
    assert not any("highlight" in p for p in paths if p.startswith("/drake/illustration_"))
    assert summary.arrow_slots[0] >= 1 and summary.arrow_slots[1] == 0
    assert "/drake/illustration/contact_forces/arrow_0/shaft/unit" in paths
    assert "/drake/illustration/contact_forces/arrow_0/tip/cone" in paths


def test_box_states_known_answers(topple):
    scene = topple[0]
    board_z = scene.shelf.top_height + 0.11
    p = np.array([[[0.6, -0.15, board_z], [0.47, 0.0, board_z]],
                  [[0.6, -0.15, board_z], [0.47, 0.0, board_z]],
                  [[0.6, -0.15, board_z], [0.47, 0.6, 0.1]]])
    upright = [1.0, 0.0, 0.0, 0.0]
    tilted = [np.cos(0.25), np.sin(0.25), 0.0, 0.0]  # 0.5 rad about x: above max_tilt
    slight = [np.cos(0.1), np.sin(0.1), 0.0, 0.0]  # 0.2 rad: upright enough
    quats = np.array([[upright, slight], [upright, tilted], [upright, tilted]])
    states = box_states(scene, p, quats, CFG)
    np.testing.assert_array_equal(states, [[0, 0], [0, 1], [0, 2]])


def test_arrow_frames_keep_the_largest_forces():
    rows = np.array([[0, 0, 0, 1, 0, 0, f] for f in (0.01, 3.0, 1.0, 7.0, 2.0)], dtype=float)
    rec = Recording(30.0, ("a",), np.array([0.0]), np.zeros((1, 1, 3)),
                    np.array([[[1.0, 0, 0, 0]]]), np.zeros((1, 10)), (rows,),
                    (np.zeros(5, dtype=int),))
    config = Config(viz=replace(CFG.viz, max_arrows=3))
    (drawn,) = arrow_frames(rec, config)
    np.testing.assert_array_equal(drawn[:, 6], [7.0, 3.0, 2.0])
    (drawn,) = arrow_frames(rec, Config(viz=replace(CFG.viz, min_force=2.5)))
    np.testing.assert_array_equal(drawn[:, 6], [7.0, 3.0])


def test_replay_rejects_duplicate_labels_and_empty_views(topple):
    scene, trajectory = topple[:2]
    view = PlanView("physics", Candidate(0.0, "ok", trajectory=trajectory))
    with pytest.raises(ValueError, match="labels must differ"):
        record_replay(scene, [view, view], CFG, Meshcat())
    with pytest.raises(ValueError, match="nothing to replay"):
        record_replay(scene, [], CFG, Meshcat())
