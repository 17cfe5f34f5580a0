"""The bounds on Sec. V's controls and the solver's settings of each stage.

A control u_t is the next knot's configuration q^(t+1) (8: the 7 arm joints in rad, the
gripper opening in m). `control_bounds` are the PR2's joint limits (the continuous rolls
bounded to +-ROLL_BOUND) and the gripper's [0, GRIPPER_MAX_OPENING]; `knot_bounds` pins some
of them to a reference path; `max_steps` is the speed limit per knot interval; `solver_settings`
turns `PhysicsConfig`'s line search, trust region and stop rules into `ilqr.ILQRSettings`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from drake_clutter.common.config import Config, PhysicsConfig
from drake_clutter.phi.state import ARM_DIM
from drake_clutter.robot import pr2
from drake_clutter.solvers import ilqr

ROLL_BOUND = 4 * np.pi  # rad, bound of the continuous rolls' controls; ours: two turns either
# way is more than any reach needs, and a bound keeps a bad feedback gain from sending phi a
# control of 1e200 rad (seen on the default scene)
GRIPPER = ARM_DIM - 1  # the control's column of the gripper opening (m)


def max_steps(config: PhysicsConfig, knot_time: float) -> np.ndarray:
    """The largest move per knot interval of each TRAJECTORY_JOINTS coordinate (rad; m for
    the opening) at ``speed_fraction`` of the PR2's speed limits."""
    limits = pr2.velocity_limits()
    arm = [limits[name] for name in pr2.ARM_JOINTS]
    finger = 2.0 * limits[pr2.FINGER_JOINTS[0]]  # the gap moves at twice a finger
    return config.speed_fraction * knot_time * np.array(arm + [finger])


def control_bounds() -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(u_min, u_max): the arm's joint limits (rad; +-ROLL_BOUND for the continuous rolls) and
    the gripper opening's [0, GRIPPER_MAX_OPENING] (m)."""
    limits = [(max(lo, -ROLL_BOUND), min(hi, ROLL_BOUND))
              for lo, hi in pr2.arm_joint_limits().values()]
    return (tuple(lo for lo, _ in limits) + (0.0,),
            tuple(hi for _, hi in limits) + (pr2.GRIPPER_MAX_OPENING,))


def knot_bounds(q_ref: np.ndarray, last_knot: bool = False, gripper: bool = False,
                min_final_opening: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-knot control bounds (T, 8) for iLQR about the knot path ``q_ref`` (T + 1, 8): the
    `control_bounds` at every knot, the last knot pinned to q_ref's (``last_knot``), every
    knot's gripper opening pinned to q_ref's (``gripper``), the last knot's opening at least
    ``min_final_opening`` (m; None: no such bound)."""
    lo, hi = (np.array(b, dtype=float) for b in control_bounds())
    T = len(q_ref) - 1
    lo, hi = np.tile(lo, (T, 1)), np.tile(hi, (T, 1))
    ref = np.clip(np.asarray(q_ref, dtype=float)[1:], lo, hi)
    if last_knot:
        lo[-1], hi[-1] = ref[-1], ref[-1]
    if gripper:
        lo[:, GRIPPER], hi[:, GRIPPER] = ref[:, GRIPPER], ref[:, GRIPPER]
    if min_final_opening is not None:
        lo[-1, GRIPPER] = min(max(lo[-1, GRIPPER], min_final_opening), hi[-1, GRIPPER])
    return lo, hi


def solver_settings(config: Config, iterations: int, knot_time: float | None = None,
                    bounds: tuple[np.ndarray, np.ndarray] | None = None,
                    deadline: float | None = None) -> ilqr.ILQRSettings:
    """The solver's settings (line search of `PhysicsConfig`); with ``knot_time`` (s) those of
    a phi stage: also the trust region, the failed-search stop (the
    kinematic stages need mu ~ 1 before their first step, measured on fig5/fig6) and the cost
    floor 0 (every Table I term is non-negative; fig6's first model predicted a decrease of
    6.8e5 from an objective of 2.7e3 and every rollout failed, measured). ``bounds``: per-knot
    (lo, hi) of `knot_bounds` (default: `control_bounds` at every knot). ``deadline``: a
    time.monotonic() value (s) past which the solver stops with its best path so far."""
    lo, hi = control_bounds() if bounds is None else bounds
    cfg = config.physics
    settings = ilqr.ILQRSettings(max_iterations=iterations, tolerance=cfg.tolerance,
                                 u_min=lo, u_max=hi, line_search_steps=cfg.line_search_steps,
                                 adaptive_step=cfg.adaptive_step, box_qp=cfg.box_qp,
                                 deadline=deadline)
    if knot_time is None:
        return settings
    limit = tuple(float(v) for v in cfg.step_limit_fraction * max_steps(cfg, knot_time))
    return replace(settings, cost_floor=0.0,
                   max_failed_searches=cfg.max_failed_searches, min_step=cfg.min_step,
                   step_limit=limit, trust_bounds=cfg.trust_bounds,
                   trust_adapt=cfg.trust_adapt, accept_ratio=cfg.accept_ratio,
                   reg_scale=limit if cfg.scaled_regulariser else None,
                   stall_fraction=cfg.stall_fraction, stall_iterations=cfg.stall_iterations)
