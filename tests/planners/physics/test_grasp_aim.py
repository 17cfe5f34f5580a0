"""c_grasp's aim: the candidate's pre-grasp point carried in the target's frame.

A path planned at a grasp height above the target's centre (here 0.8 of its height on fig5)
ends where it should: c_grasp vanishes there and does not pull the gripper down towards the
centre (Table I as written, ``physics.grasp_aim`` "centre", does). The aim follows the target
where phi moves or turns it, and its gradient over the target's rotation and position matches
central differences.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from drake_clutter.common.config import Config, PhysicsConfig
from drake_clutter.phi.dynamics import initial_state
from drake_clutter.phi.state import StateLayout, pose_to_box_state, scene_box_states
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import ArmGeometry, pregrasp_aim
from drake_clutter.planners.physics.objective import PhysicsObjective
from drake_clutter.planners.physics.stage import stage_problem
from drake_clutter.robot import pr2

FRACTION = 0.8  # grasp height, a fraction of the target's height: above its centre
OFFSET = pr2.PADS_BEHIND_TOOL


@pytest.fixture(scope="module")
def high_path(scene):
    """The baseline's knot path (T + 1, 8) on fig5 at alpha 0.3, grasp height 0.8."""
    config = replace(Config().baseline, grasp_height_fraction=FRACTION)
    (candidate,) = plan_baseline(scene, config, alphas=[0.3])
    assert candidate.ok, candidate.reason
    return np.asarray(candidate.trajectory.q, float)


@pytest.fixture(scope="module")
def geometry(scene):
    return ArmGeometry(scene, "capsules")


def _objective(scene, geometry, q_end, aim: str):
    layout = StateLayout(("target",))
    x0 = initial_state(layout, q_end, scene_box_states(scene))
    config = replace(PhysicsConfig(), grasp_aim=aim)
    objective = PhysicsObjective(geometry, layout, config, x0, "target", knot_time=0.2,
                                 d_safe=0.02, grasp_offset=OFFSET,
                                 aim_T=pregrasp_aim(geometry, q_end, "target", OFFSET))
    return objective, np.concatenate([x0, q_end])


def test_the_aim_is_the_pads_point_above_the_centre(scene, geometry, high_path):
    aim = pregrasp_aim(geometry, high_path[-1], "target", OFFSET)
    height = scene.target_box.size[2]
    # The pads' centre at 0.8 of the height: 0.3 of it above the centre (within IK tolerance).
    assert aim[2] == pytest.approx((FRACTION - 0.5) * height, abs=0.005)
    assert np.linalg.norm(aim[:2]) < 0.005


def test_a_path_ending_at_its_height_is_not_pulled_down(scene, geometry, high_path):
    q_end = high_path[-1]
    kept, z = _objective(scene, geometry, q_end, "pregrasp")
    centre, _ = _objective(scene, geometry, q_end, "centre")
    cfg = kept.config
    grasp = kept.state_terms(z, True)["grasp"]
    assert grasp.value < 1e-3 * cfg.w_grasp  # within 1 mm of its aim
    assert np.abs(grasp.gradient[:7]).max() < 0.1 * cfg.w_grasp  # the smoothed distance's slope
    pulled = centre.state_terms(z, True)["grasp"]
    assert pulled.value > 0.03 * cfg.w_grasp  # 4.5 cm above the centre
    # The descent step of "centre" over the arm moves the pads' point down.
    dp_dq = geometry.tool(q_end)[2] - OFFSET * geometry.tool_axis(q_end, 0)[1]
    assert (dp_dq @ -pulled.gradient[:8])[2] < 0.0


def test_the_aim_follows_the_target_and_its_gradient_matches(scene, geometry, high_path):
    q_end = high_path[-1]
    objective, _ = _objective(scene, geometry, q_end, "pregrasp")
    layout = objective.layout
    start = scene_box_states(scene)["target"]
    turned = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), start[4:7] + [0.01, -0.02, 0.005])
    q = q_end + 0.02
    x = initial_state(layout, q, {"target": pose_to_box_state(turned)})
    z = np.concatenate([x, q])
    # Where the pads' point would have to be: the aim carried by the turned target.
    shifted = objective.state_terms(z, True)["grasp"].value
    moved_q = _pads(geometry, q)
    distance = np.linalg.norm(moved_q - turned.multiply(objective.aim_T))
    eps = objective.config.grasp_smoothing
    assert shifted == pytest.approx(objective.config.w_grasp
                                    * (np.hypot(distance, eps) - eps), rel=1e-9)
    term = objective.state_terms(z, True)["grasp"]

    def value(d):
        moved = np.concatenate([layout.retract(z[:layout.nx], d[:layout.ndx]),
                                z[layout.nx:] + d[layout.ndx:]])
        return objective.state_terms(moved, True)["grasp"].value

    step = 1e-6
    numeric = np.array([(value(step * e) - value(-step * e)) / (2 * step)
                        for e in np.eye(objective.nz)])
    rotation = slice(8, 11)  # the target's rotation vector columns
    assert np.abs(numeric[rotation]).max() > 1.0  # the aim sits off the centre: turning moves it
    np.testing.assert_allclose(term.gradient, numeric, atol=1e-4 * np.abs(numeric).max())


def _pads(geometry, q):
    return geometry.tool(q)[0] - OFFSET * geometry.tool_axis(q, 0)[0]


def test_a_phi_stage_aims_at_its_paths_pregrasp(scene, high_path):
    """The full stage's objective, phi settled about the high path: c_grasp at the path's last
    knot is near 0, with the aim taken from the path or passed in."""
    config = replace(Config(), dynamics=replace(Config().dynamics, workers=0))
    geometry = ArmGeometry(scene, "capsules")
    aim = pregrasp_aim(geometry, high_path[-1], scene.target, OFFSET)
    for aim_T in (None, aim):
        with stage_problem(PlanningContext(scene, config), high_path, "capsules",
                           aim_T=aim_T) as problem:
            objective = getattr(problem.objective, "objective", problem.objective)  # HoldTail
            np.testing.assert_allclose(objective.aim_T, aim, atol=1e-12)
            nx = problem.dynamics.layout.nx
            z_end = np.concatenate([problem.z0[:nx], high_path[-2]])
            z_end[:8] = high_path[-1]
            value = objective.state_terms(z_end, True)["grasp"].value
            assert value < 0.005 * config.physics.w_grasp  # settling moves the target < 5 mm
