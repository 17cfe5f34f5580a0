"""Hand-made scenes and scripted reaches for the judge's tests and the replay tests.

The scenes stand the robot with its right shoulder at y = 0 in front of a bookshelf or fridge
board; ``scripted_reach`` drives the tool frame along straight segments between (x, y)
waypoints (W, m) at a fixed height with the gripper horizontal and facing +x (Drake IK on the
planning world every centimetre, linear in joint space between).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.scene.scenes import (
    BoxObject,
    RobotPlacement,
    Scene,
    Shelf,
    Walls,
    validate_scene,
)
from drake_clutter.trajectory import Trajectory, trajectory_coordinates
from drake_clutter.worlds.drake_world import build_planning_world

CONFIG = EvaluationConfig()
BOOKSHELF = Shelf("bookshelf", depth=0.4, width=0.8, thickness=0.03, top_height=0.75,
                  center_xy=(0.6, 0.0))
FRIDGE = Shelf("fridge", depth=0.4, width=0.6, thickness=0.03, top_height=0.75,
               center_xy=(0.6, 0.0), walls=Walls(thickness=0.02, height=0.36))
ROBOT = RobotPlacement(base_pose=(0.0, 0.188, 0.0), torso_height=0.2093)  # shoulder at y = 0
HAND_Z = 0.85  # m, tool frame height: 10 cm above the boards, clear of their front edges
NOMINAL_ARM = (-0.7, 0.9, -1.5, -2.1, 2.3, -1.2, -2.0)  # rad, elbow out to the right


def make_box(name, size, xy, density=300.0, friction=0.5):
    """A box of full ``size`` (m) resting on the board at planar ``xy`` (W, m), yaw 0."""
    return BoxObject(name, size, (xy[0], xy[1], 0.0), density, friction)


def make_scene(name, shelf, boxes) -> Scene:
    """A validated scene of ``boxes`` on ``shelf``, the robot at ROBOT, the target "target"."""
    return validate_scene(Scene(name, shelf, ROBOT, "target", tuple(boxes)))


def make_target(xy, size=(0.05, 0.05, 0.15)):
    """The target box, 5 x 5 x 15 cm by default, at planar ``xy`` (W, m)."""
    return make_box("target", size, xy)


class _Reach:
    """IK for a horizontal gripper facing +x at HAND_Z on a scene's planning world."""

    def __init__(self, scene: Scene):
        self.world = build_planning_world(scene)
        plant = self.world.plant
        self.context = plant.GetMyMutableContextFromRoot(
            self.world.diagram.CreateDefaultContext())
        self.q_default = plant.GetPositions(self.context)
        self.robot = self.world.robot_position_indices()
        self.others = np.setdiff1d(np.arange(len(self.q_default)), self.robot)

    def solve(self, p_WG, opening, q_guess, q_near):
        plant, idx = self.world.plant, self.robot
        ik = InverseKinematics(plant, self.context, with_joint_limits=True)
        q = ik.q()
        ik.AddPositionConstraint(self.world.tool_frame, [0, 0, 0], plant.world_frame(),
                                 p_WG - 1e-4, p_WG + 1e-4)
        ik.AddOrientationConstraint(plant.world_frame(), RotationMatrix(), self.world.tool_frame,
                                    RotationMatrix(), 1e-3)
        prog = ik.get_mutable_prog()
        fixed = self.q_default[self.others]
        prog.AddBoundingBoxConstraint(fixed, fixed, q[self.others])
        prog.AddBoundingBoxConstraint([opening / 2] * 2, [opening / 2] * 2, q[idx[7:]])
        prog.AddQuadraticErrorCost(np.eye(7), q_near, q[idx[:7]])
        guess = self.q_default.copy()
        guess[idx] = np.r_[q_guess, opening / 2, opening / 2]
        prog.SetInitialGuess(q, guess)
        result = Solve(prog)
        return result.GetSolution(q)[idx] if result.is_success() else None

    def first(self, p_WG, opening):
        rng = np.random.default_rng(0)
        low = np.maximum(self.world.plant.GetPositionLowerLimits()[self.robot[:7]], -3.0)
        high = np.minimum(self.world.plant.GetPositionUpperLimits()[self.robot[:7]], 3.0)
        guess = np.array(NOMINAL_ARM)
        for _ in range(30):
            q = self.solve(p_WG, opening, guess, np.array(NOMINAL_ARM))
            if q is not None:
                return q
            guess = rng.uniform(low, high)
        raise AssertionError(f"no IK solution at {p_WG}")


def scripted_reach(scene: Scene, waypoints, speed=0.1, opening=0.09, step=0.01,
                   z=HAND_Z) -> Trajectory:
    """The tool frame through (x, y) waypoints (W) at height ``z``, straight segments at
    ``speed`` m/s, the gripper open by ``opening`` m: IK every ``step`` m, linear in joint
    space between."""
    points = [np.array([*waypoints[0], z])]
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        a, b = np.array([*a, z]), np.array([*b, z])
        n = max(1, math.ceil(np.linalg.norm(b - a) / step))
        points += [a + (b - a) * k / n for k in range(1, n + 1)]
    reach = _Reach(scene)
    q = reach.first(points[0], opening)
    rows = [q]
    for p in points[1:]:
        q = reach.solve(p, opening, q[:7], q[:7])
        assert q is not None, f"no IK solution at {p}"
        rows.append(q)
    times = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))] / speed
    return Trajectory(times, trajectory_coordinates(np.array(rows)))
