"""The judge of every plan: hard-contact replay in Bullet and the outcome classes of Sec. III.

`evaluate(scene, trajectory)` builds a fresh `bullet_world` (the evaluation geometry of the arm,
hard contacts, another engine than the planners' phi), replays the trajectory and classifies
what happened. It sees only a `Scene` and a `Trajectory`, never a planner.

Replay (Sec. III: "up-sampling the candidate trajectories and executing them"). The arm is
**kinematic**, as OpenRAVE's robot in the paper's Bullet set-up: every ``monitor_interval``
steps each arm joint gets a velocity motor command that lands it on the plan's (linearly
interpolated) position at the next update, with a force ceiling (``arm_max_force``) far above
any contact load, so gravity and pushed boxes never bend the path. Why not position control
at the PR2's effort limits: 30 N m cannot even hold the arm up (the real PR2 has a spring
counterbalance), and the paper's failure modes are defined for an arm that goes where the plan
says. The fingers use the PR2's finger effort (N), so a box between them stops them as it would
stop the real gripper. After the last knot the arm holds still and the simulation runs until
every box is at rest (``rest_speed``, ``rest_angular_speed`` for ``rest_hold_time``) or
``settle_time_cap`` has passed (then ``Outcome.settled`` is False and the classes below are
taken on the state at the cap).

Classes (Sec. III) and thresholds (`EvaluationConfig`):

* grasped - at the end the target is in the pre-grasp zone of the gripper: a box in the tool
  frame G between the pads' inner faces, along the pads' length extended by ``zone_margin``
  and over the pads' height (`zone_extent`); the target's centre lies within its length, the
  target fits between the pads and spans their height (`target_zone_reason`); and no other box
  reaches into the zone by more than ``intrusion_tolerance`` (`grasp_check`);
* tipped - an obstacle's z axis is tilted more than ``max_tilt`` from W's z (a toppled target
  fails the grasp test instead);
* fallen - a box's centre is off the board's footprint or below its top surface;
* kinematic failure - the plan leaves the PR2's joint position/velocity limits (checked before
  simulating), or while simulating: an arm joint lags its planned position by more than
  ``max_tracking_error``; the arm sinks more than ``static_penetration`` into the shelf or
  presses on it with more than ``max_static_force`` (mean over ``force_window``); or a box is
  pressed into the shelf with more than ``max_static_force`` beyond its own weight (same mean,
  so the short impact of a toppling box does not count). The simulation stops there: the
  trajectory "cannot be simulated to completion" (Sec. III).

Precedence when several apply: kinematic_failure > objects_falling > failure_to_grasp >
partial_success > success (`classify`). Falling beats a failed grasp because it is the worse
event and Sec. III excludes any fallen object from (partial) success; a kinematic failure
invalidates everything after it. ``planner_failure`` marks a candidate without a trajectory.

Scene score (Sec. VI-B): success if any candidate succeeds, partial_success if the best is a
partial success, else failure (`scene_score`).

The optional grasp-and-lift check (beyond the paper, `lift_check`) closes the fingers on the
target and raises the tool frame ``lift_height``; it is recorded beside the outcome and never
changes it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import EvaluationConfig, check_config
from drake_clutter.evaluation.lift_check import lift_check
from drake_clutter.evaluation.outcome import (
    BoxOutcome,
    GraspCheck,
    Outcome,
    OutcomeKind,
    classify,
    outcome_grade,
    scene_score,
)
from drake_clutter.evaluation.recording import Recorder
from drake_clutter.evaluation.robust import perturbed_scene, summarise
from drake_clutter.robot import pr2
from drake_clutter.scene.grading import (
    off_the_board,
    target_zone_reason,
    tilt_angle,
    zone_extent,
)
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import (
    TRAJECTORY_JOINTS,
    Candidate,
    PlanFileError,
    Trajectory,
    plan_limit_violation,
    robot_positions,
)
from drake_clutter.worlds import bullet_world as bw

_ARM = slice(1, 8)  # arm joints within MOTOR_ORDER
_FINGERS = slice(8, 10)


# ----------------------------------------------------------------------------- plan checks


# ----------------------------------------------------------------------------- replay


class _Monitor:
    """Largest errors and forces seen, and the first kinematic failure (Sec. III)."""

    def __init__(self, world: bw.BulletWorld, config: EvaluationConfig):
        self.config = config
        self.names = world.box_names
        period = config.monitor_interval * config.sim_dt
        self.window = max(1, round(config.force_window / period))
        self.box_excess = np.zeros((self.window, len(world.boxes)))
        self.arm_static = np.zeros(self.window)
        self.samples = 0
        self.weights = world.box_masses * bw.GRAVITY
        self.forces = dict.fromkeys(("arm_box", "arm_static", "box_static", "arm_static_mean",
                                     "box_static_excess_mean", "arm_static_penetration"), 0.0)
        self.tracking_error = 0.0
        self.finger_error = 0.0
        self.failure = ""

    def _fail(self, reason: str, t: float) -> None:
        if not self.failure:
            self.failure = f"{reason} (t = {t:.2f} s)"

    def track(self, q: np.ndarray, q_desired: np.ndarray, t: float) -> None:
        """Compares the joint positions (MOTOR_ORDER) with where the plan has them at ``t``."""
        lag = np.abs(q - q_desired)
        arm = lag[_ARM]
        j = int(np.argmax(arm))
        self.tracking_error = max(self.tracking_error, float(arm[j]))
        self.finger_error = max(self.finger_error, float(lag[_FINGERS].max()))
        if arm[j] > self.config.max_tracking_error:
            self._fail(f"the arm cannot follow the trajectory: {pr2.ARM_JOINTS[j]} lags "
                       f"{arm[j]:.3f} rad (limit {self.config.max_tracking_error:g} rad)", t)

    def contacts(self, world: bw.BulletWorld, t: float) -> None:
        """Reads the contact forces after a step and checks the force and penetration limits."""
        sample = bw.contact_sample(world)
        slot = self.samples % self.window
        self.samples += 1
        self.box_excess[slot] = sample.box_static - self.weights
        self.arm_static[slot] = sample.arm_static
        box_mean = self.box_excess.mean(axis=0)
        arm_mean = float(self.arm_static.mean())
        worst = int(np.argmax(box_mean))
        peaks = {"arm_box": sample.arm_box, "arm_static": sample.arm_static,
                 "box_static": float(sample.box_static.max(initial=0.0)),
                 "arm_static_mean": arm_mean, "box_static_excess_mean": float(box_mean[worst]),
                 "arm_static_penetration": sample.arm_static_depth}
        for key, value in peaks.items():
            self.forces[key] = max(self.forces[key], float(value))
        limit = self.config.max_static_force
        if sample.arm_static_depth > self.config.static_penetration:
            self._fail(f"the arm moves through static geometry: {sample.arm_static_link} "
                       f"{sample.arm_static_depth * 1e3:.1f} mm deep", t)
        elif arm_mean > limit:
            self._fail(f"the arm presses on static geometry with {arm_mean:.1f} N "
                       f"({sample.arm_static_link}; limit {limit:g} N)", t)
        elif box_mean[worst] > limit:
            self._fail(f"box '{self.names[worst]}' pushed into static geometry with "
                       f"{box_mean[worst]:.1f} N beyond its weight (limit {limit:g} N)", t)


def _replay(world: bw.BulletWorld, trajectory: Trajectory, config: EvaluationConfig,
            monitor: _Monitor, recorder: Recorder | None = None) -> tuple[float, np.ndarray]:
    """Drives the arm along the plan (up-sampled to sim_dt); returns (simulated time, the last
    planned MOTOR_ORDER positions). Stops early at a kinematic failure. ``recorder`` (if any)
    takes its frames from the updates."""
    dt, every = config.sim_dt, config.monitor_interval
    num_steps = max(1, math.ceil(trajectory.duration / dt - 1e-9))
    marks = np.r_[np.arange(0, num_steps, every), num_steps]  # steps of the motor updates
    planned = trajectory.at(trajectory.times[0] + marks * dt)
    q_plan = bw.motor_positions(world, robot_positions(planned))
    bw.reset_robot(world, q_plan[0])
    if recorder is not None:
        recorder.sample(world, 0.0)
    forces = bw.motor_forces(config)
    for u in range(len(marks) - 1):
        span = (marks[u + 1] - marks[u]) * dt
        q = bw.joint_positions(world)
        monitor.track(q, q_plan[u], marks[u] * dt)
        bw.command_velocities(world, (q_plan[u + 1] - q) / span, forces)
        bw.step(world, int(marks[u + 1] - marks[u]))
        monitor.contacts(world, marks[u + 1] * dt)
        if recorder is not None:
            recorder.sample(world, marks[u + 1] * dt)
        if monitor.failure:
            return float(marks[u + 1] * dt), q_plan[-1]
    monitor.track(bw.joint_positions(world), q_plan[-1], num_steps * dt)
    return float(num_steps * dt), q_plan[-1]


def _settle(world: bw.BulletWorld, q_hold: np.ndarray, config: EvaluationConfig,
            monitor: _Monitor, t: float, recorder: Recorder | None = None
            ) -> tuple[float, bool]:
    """Holds the arm still until every box is at rest or the cap; returns (time, settled)."""
    dt, every = config.sim_dt, config.monitor_interval
    forces = bw.motor_forces(config)
    updates = math.ceil(config.settle_time_cap / (every * dt) - 1e-9)
    still = 0.0
    for _ in range(updates):
        monitor.track(bw.joint_positions(world), q_hold, t)
        bw.hold(world, q_hold, forces, every * dt)
        bw.step(world, every)
        t += every * dt
        monitor.contacts(world, t)
        if recorder is not None:
            recorder.sample(world, t)
        if monitor.failure:
            return t, False
        speed, spin = bw.box_speeds(world)
        resting = bool(np.all(speed < config.rest_speed)
                       and np.all(spin < config.rest_angular_speed))
        still = still + every * dt if resting else 0.0
        if still >= config.rest_hold_time - 1e-9:
            return t, True
    return t, False


# ----------------------------------------------------------------------------- findings


def _box_outcomes(scene: Scene, p_start: np.ndarray, p_end: np.ndarray, R_end: np.ndarray,
                  config: EvaluationConfig) -> tuple[BoxOutcome, ...]:
    tilts = tilt_angle(R_end)
    fallen = off_the_board(scene, p_end)
    moved = np.linalg.norm(p_end - p_start, axis=1)
    return tuple(BoxOutcome(box.name, float(moved[i]), float(tilts[i]), bool(fallen[i]),
                            bool(not fallen[i] and tilts[i] > config.max_tilt),
                            tuple(float(v) for v in p_end[i]))
                 for i, box in enumerate(scene.boxes))


def grasp_check(world: bw.BulletWorld, config: EvaluationConfig) -> GraspCheck:
    """Sec. III's grasp test on the world's current state: is the target in the pre-grasp zone
    of the gripper (`target_zone_reason`) with no other box reaching into the zone by more than
    ``intrusion_tolerance``?"""
    scene = world.scene
    p_WG, R_WG = bw.tool_pose(world)
    opening = float(pr2.gripper_opening(bw.joint_positions(world)[_FINGERS].mean()))
    p_WB, R_WB = bw.box_poses(world)
    i = world.box_names.index(scene.target)
    p_GT = R_WG.T @ (p_WB[i] - p_WG)
    reason = target_zone_reason(p_GT, R_WG.T @ R_WB[i], scene.target_box.size, opening, config)
    centre, half = zone_extent(opening, config)
    others = [k for k in range(len(world.boxes)) if k != i]
    depths = bw.region_penetrations(world, half, p_WG + R_WG @ centre, R_WG,
                                    [world.boxes[k] for k in others])
    intruders = tuple(world.box_names[k] for k, d in zip(others, depths, strict=True)
                      if d > config.intrusion_tolerance)
    if not reason and intruders:
        reason = "another box is in the gripper: " + ", ".join(intruders)
    return GraspCheck(not reason, reason, tuple(float(v) for v in p_GT), opening, intruders)


def _unsimulated(scene: Scene, trajectory: Trajectory, reason: str) -> Outcome:
    boxes = tuple(BoxOutcome(b.name, 0.0, 0.0, False, False,
                             (b.pose[0], b.pose[1], scene.box_center_z(b))) for b in scene.boxes)
    return Outcome(OutcomeKind.KINEMATIC_FAILURE, reason, boxes,
                   trajectory_time=trajectory.duration)


def evaluate(scene: Scene, trajectory: Trajectory, config: EvaluationConfig | None = None,
             lift: bool = False, record_fps: float | None = None, robust: int | None = None,
             seed: int | None = None) -> Outcome:
    """Replays ``trajectory`` in a fresh Bullet world of ``scene`` and classifies the result
    (Sec. III; see the module docstring). With ``lift``, the grasp-and-lift check runs after
    the classification (not after a kinematic failure) and is recorded in ``Outcome.lift``.
    With ``record_fps``, ``Outcome.recording`` holds the replay's frames at that rate (see
    `recording`; reading only, the outcome is the same).

    The robust judge: with ``robust`` = K > 1 replays (default ``config.robust_replays``) and
    ``seed`` (default ``config.robust_seed``), the plan is replayed again in K - 1 perturbed
    worlds (`robust.perturbed_scene`); the outcome is the nominal one, with
    ``Outcome.robust`` holding the K classes and grades, and ``wall_time`` all K replays.

    Deterministic: the same scene, trajectory and configuration give the same Outcome (but for
    ``wall_time``). Raises ValueError for a trajectory over other joints than TRAJECTORY_JOINTS
    and ConfigError for a setting outside its declared range (`config.check_config`).
    """
    config = config or EvaluationConfig()
    changes = {"robust_replays": robust, "robust_seed": seed}
    config = replace(config, **{k: v for k, v in changes.items() if v is not None})
    check_config(config, section="evaluation")
    started = time.perf_counter()
    nominal = _replay_once(scene, trajectory, config, lift, record_fps)
    if config.robust_replays == 1:
        return _with_wall_time(nominal, started)
    outcomes = [nominal] + [_replay_once(perturbed_scene(scene, config, k), trajectory, config,
                                         lift=False, record_fps=None)
                            for k in range(1, config.robust_replays)]
    summary = summarise(config.robust_seed, [o.kind for o in outcomes],
                        [outcome_grade(o) for o in outcomes])
    return _with_wall_time(replace(nominal, robust=summary), started)


def _replay_once(scene: Scene, trajectory: Trajectory, config: EvaluationConfig, lift: bool,
                 record_fps: float | None) -> Outcome:
    """One replay and its classification (`evaluate` without the robust replays)."""
    violation = plan_limit_violation(trajectory, config)
    if violation:
        return _unsimulated(scene, trajectory, f"the arm cannot follow the trajectory: "
                                               f"{violation}")
    with bw.build_bullet_world(scene, config) as world:
        p_start, _ = bw.box_poses(world)
        monitor = _Monitor(world, config)
        recorder = None if record_fps is None else Recorder(record_fps)
        t, q_hold = _replay(world, trajectory, config, monitor, recorder)
        settled = False
        if not monitor.failure:
            t, settled = _settle(world, q_hold, config, monitor, t, recorder)
        p_end, R_end = bw.box_poses(world)
        boxes = _box_outcomes(scene, p_start, p_end, R_end, config)
        grasp = grasp_check(world, config)
        tipped = [b.name for b in boxes if b.tipped and b.name != scene.target]
        kind, reason = classify(monitor.failure, [b.name for b in boxes if b.fallen],
                                grasp.reason, tipped)
        recording = None if recorder is None else recorder.finish(world, t)
        lifted = lift_check(world, q_hold, config) if lift and not monitor.failure else None
    outcome = Outcome(kind, reason, boxes, grasp, monitor.forces, monitor.tracking_error,
                      monitor.finger_error, t, trajectory.duration, settled, lifted,
                      recording=recording)
    return outcome


def _with_wall_time(outcome: Outcome, started: float) -> Outcome:
    return replace(outcome, wall_time=time.perf_counter() - started)


# ----------------------------------------------------------------------------- candidates


def evaluate_candidates(scene: Scene, candidates: Sequence[Candidate],
                        config: EvaluationConfig | None = None,
                        lift: bool = False, record_fps: float | None = None) -> list[Outcome]:
    """One Outcome per candidate (same order); a candidate without a usable trajectory gets
    kind ``planner_failure`` with the planner's status and reason. ``record_fps``: as in
    `evaluate`."""
    outcomes = []
    for candidate in candidates:
        if candidate.ok:
            outcomes.append(evaluate(scene, candidate.trajectory, config, lift, record_fps))
        else:
            why = candidate.status + (f": {candidate.reason}" if candidate.reason else "")
            outcomes.append(Outcome(OutcomeKind.PLANNER_FAILURE, why))
    return outcomes


OUTCOMES_FORMAT = "drake_clutter.outcomes/1"


def check_plan(scene: Scene, plan_scene: str, candidates: Sequence[Candidate], path) -> None:
    """Raises PlanFileError (naming the file and field) when a plan does not belong to
    ``scene`` or a candidate's trajectory is over other joints than TRAJECTORY_JOINTS."""
    if plan_scene and plan_scene != scene.name:
        raise PlanFileError(path, "scene", f"the plan is for scene '{plan_scene}', not "
                                           f"'{scene.name}'")
    for i, candidate in enumerate(candidates):
        names = candidate.trajectory.joint_names if candidate.trajectory is not None else None
        if names is not None and names != TRAJECTORY_JOINTS:
            raise PlanFileError(path, f"candidates[{i}].trajectory.joint_names",
                                f"expected {list(TRAJECTORY_JOINTS)}")


def outcomes_document(scene: Scene, candidates: Sequence[Candidate],
                      outcomes: Sequence[Outcome], plan: str = "") -> dict:
    """The JSON document of a scene's evaluated candidates and its scene score (Sec. VI-B);
    with robust outcomes also the scene's robust success (its best candidate's P(success))."""
    doc = {"format": OUTCOMES_FORMAT, "scene": scene.name, "plan": str(plan),
           "scene_score": scene_score(o.kind for o in outcomes),
           "candidates": [{"alpha": c.alpha, "planner": c.planner, "status": c.status.value,
                           "outcome": o.to_data()}
                          for c, o in zip(candidates, outcomes, strict=True)]}
    robust = [o.robust.p_success for o in outcomes if o.robust is not None]
    if robust:
        doc["scene_p_success"] = max(robust)
    return doc


def outcome_table(candidates: Sequence[Candidate], outcomes: Sequence[Outcome]) -> str:
    """A plain-text table, one row per candidate: outcome, largest box displacement (cm),
    tipped/fallen counts, largest windowed shelf force beyond a box's weight (N), largest arm
    lag (rad), the lift result and the reason."""
    robust = any(o.robust is not None for o in outcomes)
    header = (f"{'#':>3} {'planner':10} {'alpha':>6} {'outcome':18} {'moved':>6} {'tip':>3} "
              f"{'fall':>4} {'F_shelf':>7} {'lag':>6} {'lift':5} "
              + (f"{'P(s)':>5} {'P(s|p)':>6} " if robust else "") + "reason")
    rows = [header]
    for i, (c, o) in enumerate(zip(candidates, outcomes, strict=True)):
        moved = max((b.displacement for b in o.boxes), default=0.0) * 100
        lift = "-" if o.lift is None else ("yes" if o.lift.lifted else "no")
        spread = ""
        if robust:
            r = o.robust
            spread = (f"{'-':>5} {'-':>6} " if r is None else
                      f"{r.p_success:>5.2f} {r.p_success_or_partial:>6.2f} ")
        rows.append(f"{i:>3} {c.planner[:10]:10} {c.alpha:>6.3f} {o.kind:18} {moved:>6.1f} "
                    f"{sum(b.tipped for b in o.boxes):>3} {sum(b.fallen for b in o.boxes):>4} "
                    f"{o.forces.get('box_static_excess_mean', 0.0):>7.1f} "
                    f"{o.tracking_error:>6.3f} {lift:5} {spread}{o.reason}")
    return "\n".join(rows)
