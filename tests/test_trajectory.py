"""Trajectories, candidates and plan files."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.trajectory import (
    Candidate,
    PlanFileError,
    Trajectory,
    load_plan,
    robot_positions,
    save_plan,
    trajectory_coordinates,
)


def _traj():
    times = np.array([0.0, 0.2, 0.4])
    q = np.zeros((3, 8))
    q[:, 0] = [0.0, 0.5, 1.0]
    q[:, 7] = [0.08, 0.04, 0.0]
    return Trajectory(times, q)


def test_interpolation_and_resampling():
    traj = _traj()
    assert traj.at(0.1)[0] == pytest.approx(0.25)
    assert traj.at(1.0)[0] == pytest.approx(1.0)  # held after the end
    fine = traj.resampled(0.05)
    assert fine.num_knots == 9 and fine.times[-1] == pytest.approx(0.4)
    np.testing.assert_allclose(fine.q[-1], traj.q[-1])


def test_robot_position_conversion_round_trips():
    q = _traj().q
    robot = robot_positions(q)
    assert robot.shape == (3, 9)
    np.testing.assert_allclose(robot[:, 7], q[:, 7] / 2)
    np.testing.assert_allclose(trajectory_coordinates(robot), q)


@pytest.mark.parametrize("times,q", [([0.0], np.zeros((1, 8))), ([0.0, 0.0], np.zeros((2, 8))),
                                     ([0.0, 1.0], np.zeros((2, 7))),
                                     ([0.0, 1.0], np.full((2, 8), np.nan))])
def test_bad_trajectories_are_rejected(times, q):
    with pytest.raises(ValueError):
        Trajectory(np.array(times), q)


def test_plan_file_round_trip(tmp_path):
    cands = [Candidate(0.1, "ok", trajectory=_traj(), timings={"ik": 0.01}),
             Candidate(-0.3, "ik_failed", reason="no IK solution for the start pose")]
    path = save_plan(tmp_path / "p.json", "fig5", cands, {"planner": "baseline"})
    scene, loaded, doc = load_plan(path)
    assert scene == "fig5" and doc["planner"] == "baseline"
    assert loaded[0].trajectory == cands[0].trajectory and loaded[0].ok
    assert not loaded[1].ok and loaded[1].reason == cands[1].reason


@pytest.mark.parametrize("text,needle", [("{", "not valid JSON"), ("[]", "not a plan file"),
                                         ('{"format": "drake_clutter.plan/1", "candidates": [{}]}',
                                          "malformed")])
def test_bad_plan_files(tmp_path, text, needle):
    path = tmp_path / "p.json"
    path.write_text(text)
    with pytest.raises(PlanFileError, match=needle):
        load_plan(path)
