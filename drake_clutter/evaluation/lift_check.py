"""Grasp-and-lift check (beyond the paper): does the target come away in the hand?

Sec. III judges a plan by where the target ends (in the pre-grasp zone); this check goes one
step further on the same Bullet world after the replay: close the fingers with the PR2's finger
effort and speed, raise the tool frame ``lift_height`` straight up in W keeping its orientation
(resolved-rate control on the tool Jacobian, the torso held), hold, and look. The result is
recorded beside the paper's outcome and never changes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.robot import pr2
from drake_clutter.worlds import bullet_world as bw

_ARM = slice(1, 8)  # arm joints within bullet_world.MOTOR_ORDER


@dataclass(frozen=True)
class LiftResult:
    """Did the target come away in the hand? Rises in m (z in W)."""

    lifted: bool  # the target rose lift_fraction x lift_height and touches both fingers
    target_rise: float  # m, change of the target centre's z
    tool_rise: float  # m, change of the tool frame's z
    in_hand: bool  # the target touches both fingers at the end
    others_lifted: tuple[str, ...]  # other boxes that rose by half the lift height or more

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"lifted": self.lifted, "target_rise": self.target_rise,
                "tool_rise": self.tool_rise, "in_hand": self.in_hand,
                "others_lifted": list(self.others_lifted)}


def _run(world: bw.BulletWorld, q_hold, config: EvaluationConfig, duration: float,
         finger_speed: float) -> None:
    span = config.monitor_interval * config.sim_dt
    forces = bw.motor_forces(config)
    for _ in range(math.ceil(duration / span - 1e-9)):
        bw.hold(world, q_hold, forces, span, finger_speed)
        bw.step(world, config.monitor_interval)


def _rise(world: bw.BulletWorld, config: EvaluationConfig, finger_speed: float) -> np.ndarray:
    """Raises the tool frame lift_height in W, orientation kept; returns the final positions."""
    span = config.monitor_interval * config.sim_dt
    forces = bw.motor_forces(config)
    p_start, R_start = bw.tool_pose(world)
    q = bw.joint_positions(world)
    updates = math.ceil(config.lift_time / span - 1e-9)
    for u in range(updates):
        p_goal = p_start + [0.0, 0.0, config.lift_height * (u + 1) / updates]
        p_WG, R_WG = bw.tool_pose(world)
        twist = np.r_[p_goal - p_WG, Rotation.from_matrix(R_start @ R_WG.T).as_rotvec()]
        q_next = q.copy()
        q_next[_ARM] += np.linalg.lstsq(bw.tool_jacobian(world, q), twist, rcond=None)[0]
        bw.hold(world, q_next, forces, span, finger_speed)
        bw.step(world, config.monitor_interval)
        q = bw.joint_positions(world)
    return q


def lift_check(world: bw.BulletWorld, q_hold: np.ndarray, config: EvaluationConfig) -> LiftResult:
    """Closes the fingers on whatever is between them while the arm holds ``q_hold``
    (MOTOR_ORDER), lifts, holds for ``lift_hold_time`` and reports (see `LiftResult`)."""
    finger_speed = pr2.velocity_limits()[pr2.FINGER_JOINTS[0]]
    i = world.box_names.index(world.scene.target)
    z_start = bw.box_poses(world)[0][:, 2]
    _run(world, q_hold, config, config.lift_close_time, finger_speed)
    z_tool = bw.tool_pose(world)[0][2]
    q_top = _rise(world, config, finger_speed)
    _run(world, q_top, config, config.lift_hold_time, finger_speed)
    rise = bw.box_poses(world)[0][:, 2] - z_start
    in_hand = set(pr2.FINGER_LINKS) <= bw.touching_links(world, world.boxes[i])
    others = tuple(name for k, name in enumerate(world.box_names)
                   if k != i and rise[k] >= config.lift_height / 2)
    return LiftResult(bool(in_hand and rise[i] >= config.lift_fraction * config.lift_height),
                      float(rise[i]), float(bw.tool_pose(world)[0][2] - z_tool), bool(in_hand),
                      others)
