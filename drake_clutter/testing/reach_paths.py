"""Baseline-like arm paths for phi's tests and benchmark (not a planner).

Sec. IV's initial path: the gripper horizontal at a height above the board, IK at a start on a
line in front of the shelf and at the pre-grasp pose on the target (IK chained along the
straight line so both ends share an arm posture), then linear interpolation in joint space.
Nothing here avoids obstacles: the path pushes through whatever stands in the way.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from drake_clutter.common.config import WorldConfig
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import trajectory_coordinates
from drake_clutter.worlds.drake_world import build_planning_world, park_positions


def _ik(world, p_WT, R_WT, q_seed, rng, tries):
    plant = world.plant
    context = plant.CreateDefaultContext()
    ik = InverseKinematics(plant, context)
    W = plant.world_frame()
    ik.AddPositionConstraint(world.tool_frame, [0, 0, 0], W, p_WT - 1e-4, p_WT + 1e-4)
    ik.AddOrientationConstraint(world.tool_frame, RotationMatrix(), W, R_WT, 1e-3)
    q, prog = ik.q(), ik.prog()
    idx = world.robot_position_indices()
    prog.AddBoundingBoxConstraint(q_seed[7:], q_seed[7:], q[idx[7:]])
    nominal = plant.GetPositions(context)
    nominal[idx] = q_seed
    prog.AddQuadraticErrorCost(0.01 * np.eye(len(nominal)), nominal, q)
    guess = nominal.copy()
    for _ in range(tries):
        prog.SetInitialGuess(q, guess)
        result = Solve(prog)
        if result.is_success():
            return result.GetSolution(q)[idx]
        guess = nominal.copy()
        guess[idx[:7]] += rng.uniform(-1.0, 1.0, 7)
    return None


def straight_reach(scene: Scene, num_knots: int = 30, height: float = 0.07,
                   start_back: float = 0.0, seed: int = 0) -> np.ndarray | None:
    """(num_knots, 8) TRAJECTORY_JOINTS rows from in front of the shelf to the target, the
    gripper horizontal at ``height`` m above the board, approaching along +x; None if IK
    fails."""
    rng = np.random.default_rng(seed)
    world = build_planning_world(scene)
    target = scene.target_box
    z = scene.shelf.top_height + height
    p_end = np.array([target.pose[0], target.pose[1], z])
    p_start = np.array([scene.shelf.front_x - start_back, target.pose[1], z])
    R = RotationMatrix(RollPitchYaw(0, 0, 0))
    q = _ik(world, p_start, R, park_positions(world, WorldConfig()), rng, tries=10)
    if q is None:
        return None
    q_start = q
    for s in np.linspace(0, 1, 6)[1:]:
        q = _ik(world, (1 - s) * p_start + s * p_end, R, q, rng, tries=3)
        if q is None:
            return None
    s = np.linspace(0, 1, num_knots)[:, None]
    return trajectory_coordinates((1 - s) * q_start + s * q)
