"""The judge in phi (beyond the paper): Sec. III's classes read on phi's rollouts of a plan.

The judge replays a plan in Bullet and sorts it into Sec. III's classes; a planner may not
(Bullet and the mesh arm are the judge's alone). This reads the same classes on phi: the plan
rolled out with its held knots after Delta (``phi_judge.hold_knots``) in each of phi's
ensemble members (`members.member_world`: member 0 the scene, members k >= 1 every box moved
and its mass and friction scaled from the planner's seeds ``[phi_judge.seed, k]``, never the
judge's), and in each member:

* **kinematic failure** - the plan leaves the PR2's joint or speed limits
  (`trajectory.plan_limit_violation`, the judge's own check), phi fails to roll it out, or
  phi's jam measure reaches ``phi_judge.jam_depth`` (`phi.jam`: the arm's commanded approach
  into a box a rigid world would not let move, largest knot of the path and the hold);
* **objects falling** - a box's centre off the board or below its top
  (`grading.off_the_board`) at the end of the hold;
* **failure to grasp** - the target not in the last knot's pre-grasp zone
  (`grading.target_zone_reason`) or another box reaching into the zone deeper than
  ``evaluation.intrusion_tolerance`` (`grading.box_overlap`);
* **partial success** - an obstacle tipped past ``evaluation.max_tilt``; else **success**;

with the judge's precedence (`grading.classify`). Each member's `PhiFindings` (what the rollout
showed, the press on a box's top recorded beside the jam) are kept beside its reading, so the
same rollouts can be read again, e.g. under another ``phi_judge.jam_depth``
(`PhiVerdict.from_findings`). Over the K members: P(success) and the expected grade class, as the
robust judge summarises its replays.
"""

from __future__ import annotations

import math
import queue
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix

from drake_clutter.common.config import Config, EvaluationConfig, PhiJudgeConfig
from drake_clutter.common.physics_config import DynamicsConfig
from drake_clutter.phi.dynamics import initial_state, make_spec
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.pruning import prune
from drake_clutter.phi.state import ARM_DIM, scene_box_states
from drake_clutter.planners.budget import past
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import ArmGeometry, path_depths
from drake_clutter.planners.members import member_world
from drake_clutter.scene.grading import (
    GRADE_CLASSES,
    OutcomeKind,
    box_overlap,
    classify,
    edge_distance,
    off_the_board,
    target_zone_ratio,
    target_zone_reason,
    tilt_angle,
    zone_extent,
)
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Trajectory, plan_limit_violation


@dataclass(frozen=True)
class PhiFindings:
    """What one member's rollout of a plan showed, before the classes' precedence: the plan's
    joint or speed limit violation ("" for none), its deepest press on a box's top with the boxes at
    rest (m; recorded, not read; None where not measured: the short form), phi's largest jam
    measure over the path and the hold (m; None where phi failed), whether phi failed, the
    boxes fallen, the obstacles tipped, why the target is not grasped ("" when it is), the
    boxes tipped or fallen (the target included), and whether the rollout was stopped (or not
    run) once a kinematic failure was certain (the box fates are then not read: `judge_paths`
    with ``complete=False``). How near the box fates came to the classes' limits (None where
    not read): the largest obstacle tilt (rad), the largest approach of a box to the board's
    edge (1 - its distance inside the footprint at the end over that at the start, unitless, at
    least 1 for a fallen box), the target's distance from the pre-grasp zone
    (`grading.target_zone_ratio`, unitless) and the deepest intrusion of another box into it
    (m)."""

    limit: str = ""
    press: float | None = 0.0
    jam: float | None = 0.0
    failed: bool = False
    fallen: tuple[str, ...] = ()
    tipped: tuple[str, ...] = ()
    grasp: str = ""
    disturbed: int = 0
    stopped: bool = False
    tilt: float | None = None
    edge: float | None = None
    zone: float | None = None
    intrusion: float | None = None

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"limit": self.limit, "press": self.press, "jam": self.jam,
                "failed": self.failed, "fallen": list(self.fallen), "tipped": list(self.tipped),
                "grasp": self.grasp, "disturbed": self.disturbed, "stopped": self.stopped,
                "tilt": self.tilt, "edge": self.edge, "zone": self.zone,
                "intrusion": self.intrusion}

    @staticmethod
    def from_data(data: dict) -> PhiFindings:
        """Inverse of `to_data`."""
        return PhiFindings(str(data["limit"]), _number(data["press"]), _number(data["jam"]),
                           bool(data["failed"]), tuple(data["fallen"]), tuple(data["tipped"]),
                           str(data["grasp"]), int(data["disturbed"]),
                           bool(data.get("stopped", False)),
                           *(_number(data.get(k)) for k in ("tilt", "edge", "zone", "intrusion")))


def _number(value) -> float | None:
    """A stored number, or None where it was not measured."""
    return None if value is None else float(value)


def _finite(value: float) -> float | None:
    """JSON's number for a margin: None for an infinite one."""
    return value if math.isfinite(value) else None


@dataclass(frozen=True)
class PhiReading:
    """One member's reading of a plan: Sec. III's class (an `OutcomeKind` value), why, the
    boxes tipped or fallen at the end of the hold, and how near the findings came to the
    classes' limits (`member_margin`, unitless; lower is better)."""

    kind: str
    reason: str
    disturbed: int = 0
    margin: float = 0.0

    @property
    def grade(self) -> int:
        """The class's grade (`grading.GRADE_CLASSES`: 0 success .. 3 kinematic failure)."""
        return GRADE_CLASSES[self.kind]


def kinematic_reason(findings: PhiFindings, config: Config) -> str:
    """The kinematic failure the findings show ("" for none): a limit violation, a failed
    rollout, or a jam of at least ``phi_judge.jam_depth``."""
    if findings.limit:
        return findings.limit
    if findings.failed:
        return "phi failed on the rollout"
    if findings.jam is not None and findings.jam >= config.phi_judge.jam_depth:
        return f"jam {findings.jam * 1e3:.1f} mm"
    return ""


def member_margin(findings: PhiFindings, config: Config) -> float:
    """How near one member's findings came to the classes' limits, unitless, lower is better:
    the largest of the quantities the classes threshold, each over its limit (the jam over
    ``phi_judge.jam_depth``, the largest obstacle tilt over ``evaluation.max_tilt``, a box's
    approach to the board's edge, the target's distance from the pre-grasp zone, the deepest
    intrusion into it over ``evaluation.intrusion_tolerance``), so above 1 where one of them
    decides a failure; infinite for a plan out of the limits or a failed rollout. A quantity
    not read (a stopped rollout's box fates) is left out."""
    if findings.limit or findings.failed:
        return math.inf
    ratios = [0.0]
    if findings.jam is not None:
        ratios.append(findings.jam / config.phi_judge.jam_depth)
    if findings.tilt is not None:
        ratios.append(findings.tilt / config.evaluation.max_tilt)
    ratios += [r for r in (findings.edge, findings.zone) if r is not None]
    if findings.intrusion is not None:
        tolerance = config.evaluation.intrusion_tolerance
        ratios.append(findings.intrusion / tolerance if tolerance > 0
                      else math.inf if findings.intrusion > 0 else 0.0)
    return float(max(ratios))


def reading_of(findings: PhiFindings, config: Config) -> PhiReading:
    """Sec. III's class of the findings with the judge's precedence (`grading.classify`)."""
    reason = kinematic_reason(findings, config)
    kind, why = classify(reason, findings.fallen, findings.grasp, findings.tipped)
    return PhiReading(kind.value, why, findings.disturbed, member_margin(findings, config))


@dataclass(frozen=True)
class PhiVerdict:
    """A plan's readings over the K members (member 0 the nominal world) and the findings
    they were read from."""

    readings: tuple[PhiReading, ...]
    findings: tuple[PhiFindings, ...] = ()

    @property
    def p_success(self) -> float:
        """Fraction of the members that read a success."""
        return sum(r.kind == OutcomeKind.SUCCESS for r in self.readings) / len(self.readings)

    @property
    def expected_grade(self) -> float:
        """Mean grade class over the members (lower is better)."""
        return float(np.mean([r.grade for r in self.readings]))

    @property
    def disturbed(self) -> float:
        """Mean boxes tipped or fallen over the members."""
        return float(np.mean([r.disturbed for r in self.readings]))

    @property
    def margin(self) -> float:
        """Mean margin over the members (`member_margin`; lower is nearer to success)."""
        return float(np.mean([r.margin for r in self.readings]))

    def key(self) -> tuple[float, float, float, float]:
        """The order of plans, best first: higher P(success), then lower expected grade, then
        the lower mean margin (nearer the classes' limits' good side), then fewer boxes
        disturbed."""
        return (-self.p_success, self.expected_grade, self.margin, self.disturbed)

    def class_key(self) -> tuple[float, float, float]:
        """`key` without the margin: the classes' reading alone (P(success), the expected
        grade, the boxes disturbed)."""
        return (-self.p_success, self.expected_grade, self.disturbed)

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"kinds": [r.kind for r in self.readings],
                "reasons": [r.reason for r in self.readings],
                "disturbed": [r.disturbed for r in self.readings],
                "margins": [_finite(r.margin) for r in self.readings],
                "margin": _finite(self.margin),
                "p_success": self.p_success, "expected_grade": self.expected_grade,
                "findings": [f.to_data() for f in self.findings]}

    @staticmethod
    def from_findings(findings, config: Config) -> PhiVerdict:
        """The verdict of per-member findings (`PhiFindings` or their data) read with
        ``config``."""
        found = tuple(f if isinstance(f, PhiFindings) else PhiFindings.from_data(f)
                      for f in findings)
        return PhiVerdict(tuple(reading_of(f, config) for f in found), found)


def box_fates(scene: Scene, geometry: ArmGeometry, final: dict[str, np.ndarray],
              evaluation: EvaluationConfig
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every scene box's pose at the end (``final``: the kept boxes' 13-number states,
    quaternion wxyz then position in W (m); a box missing from it is at rest where the scene
    put it): (positions (n, 3), rotations (n, 3, 3), fallen (n,), tipped (n,)) in scene
    order, as `grading` defines them; the target counts as tipped here too."""
    names = [b.name for b in scene.boxes]
    p, R = [], []
    for name in names:
        if name in final:
            q = np.asarray(final[name][:4], dtype=float)
            R.append(RotationMatrix(Quaternion(q / np.linalg.norm(q))).matrix())
            p.append(np.asarray(final[name][4:7], dtype=float))
        else:
            X = geometry.rest_pose(name)
            R.append(X.rotation().matrix())
            p.append(X.translation())
    p, R = np.array(p), np.array(R)
    fallen = off_the_board(scene, p)
    tipped = ~fallen & (tilt_angle(R) > evaluation.max_tilt)
    return p, R, fallen, tipped


def grasp_reading(scene: Scene, geometry: ArmGeometry, q_last: np.ndarray, p: np.ndarray,
                  R: np.ndarray, evaluation: EvaluationConfig) -> tuple[str, float, float]:
    """Why the target (scene order in p (n, 3), R (n, 3, 3), W) is not grasped at the last knot
    ``q_last`` (8,) ("" when it sits in the gripper's pre-grasp zone and no other box reaches
    into the zone deeper than ``intrusion_tolerance``: the judge's `grasp_check`), the target's
    distance from the zone (`grading.target_zone_ratio`, unitless) and the deepest intrusion
    of another box into it (m)."""
    names = [b.name for b in scene.boxes]
    i = names.index(scene.target)
    X_WG = geometry.tool_jacobian(q_last)[0]
    R_WG, p_WG = X_WG.rotation().matrix(), X_WG.translation()
    opening = float(q_last[7])
    p_GT, R_GT = R_WG.T @ (p[i] - p_WG), R_WG.T @ R[i]
    size = scene.target_box.size
    zone = target_zone_ratio(p_GT, R_GT, size, opening, evaluation)
    reason = target_zone_reason(p_GT, R_GT, size, opening, evaluation)
    centre, half = zone_extent(opening, evaluation)
    zone_W = p_WG + R_WG @ centre
    depths = {name: box_overlap(zone_W, R_WG, half, p[k], R[k], np.asarray(box.size) / 2)
              for k, (name, box) in enumerate(zip(names, scene.boxes, strict=True)) if k != i}
    deepest = max(depths.values(), default=0.0)
    if reason:
        return reason, zone, deepest
    intruders = [name for name, depth in depths.items()
                 if depth > evaluation.intrusion_tolerance]
    return (("another box is in the gripper: " + ", ".join(intruders)) if intruders else "",
            zone, deepest)


def member_findings(scene: Scene, geometry: ArmGeometry, q: np.ndarray,
                    rollout: JudgedRollout, limit: str, press: float | None,
                    evaluation: EvaluationConfig) -> PhiFindings:
    """What one member's ``rollout`` (with its jam measure) of the knot path ``q`` (T + 1, 8)
    showed, with the plan's ``limit`` violation and ``press`` depth (m) found beforehand."""
    if rollout.final_boxes is None:
        return PhiFindings(limit, press, None, failed=True)
    p, R, fallen, tipped = box_fates(scene, geometry, rollout.final_boxes, evaluation)
    names = [b.name for b in scene.boxes]
    grasp, zone, intrusion = grasp_reading(scene, geometry, q[-1], p, R, evaluation)
    obstacles = np.array([n != scene.target for n in names])
    start = edge_distance(scene, np.array([geometry.rest_pose(n).translation() for n in names]))
    approach = 1.0 - edge_distance(scene, p) / np.maximum(start, 1e-9)
    return PhiFindings(
        limit, press, rollout.jam, False,
        tuple(n for n, f in zip(names, fallen, strict=True) if f),
        tuple(n for n, t in zip(names, tipped, strict=True) if t and n != scene.target),
        grasp, int(fallen.sum() + tipped.sum()),
        tilt=float(tilt_angle(R)[obstacles].max(initial=0.0)),
        edge=float(np.max(np.where(fallen, np.maximum(approach, 1.0), approach),
                          initial=0.0)),
        zone=zone, intrusion=float(intrusion))


def plan_checks(scene: Scene, geometry: ArmGeometry, q: np.ndarray, times: np.ndarray,
                config: Config, press: bool = True) -> tuple[str, float | None]:
    """The member-independent checks of a knot path (T + 1, 8) at ``times`` (s): the judge's
    joint and speed limits ("" when kept) and the deepest press on a box's top with the boxes
    at rest (m, `geometry.path_depths`; None without ``press``: it is recorded, not read)."""
    violation = plan_limit_violation(Trajectory(np.asarray(times, float), q), config.evaluation)
    if not press:
        return violation, None
    press, _ = path_depths(geometry, q, config.starts.press_substeps,
                           config.starts.press_normal_z, (scene.target,))
    return violation, float(press)


@dataclass(frozen=True)
class JudgedRollout:
    """One path rolled out in one member's phi for the judge: every kept box's 13-number state
    at the end of the hold (quaternion wxyz, position in W (m), velocities; None where phi
    failed or the rollout stopped), the largest knot's jam measure so far (m, `phi.jam`; None
    where phi failed), whether it stopped at ``stop``, the frozen boxes it reached, and whether
    the deadline cut it (``unfinished``: it reads nothing)."""

    final_boxes: dict[str, np.ndarray] | None
    jam: float | None
    stopped: bool = False
    touched: frozenset = frozenset()
    unfinished: bool = False


UNFINISHED = JudgedRollout(None, None, unfinished=True)


def judged_rollouts(world: Scene, paths: dict[str, np.ndarray], config: Config,
                    knot_time: float, stop: float | None = None,
                    deadline: float | None = None) -> dict[str, JudgedRollout]:
    """Each knot path (T + 1, 8) rolled out in one phi of ``world`` (a member's scene, capsule
    arm, `judge_dynamics`) and held at its last knot for ``phi_judge.hold_knots``
    knots, its jam measured at every knot; one phi for all paths, pruned to them
    (`pruning.prune`; every box kept without ``phi_judge.prune``), its boxes settled once
    under the first path's start (with ``phi_judge.stepping`` "kept" in one MuJoCo world that
    every path starts from as it was settled, `MujocoPhi.keep_world`). A path whose
    rollout reaches a frozen box is rolled out again in a phi with those boxes kept, up to
    ``dynamics.prune_rounds`` times. ``stop`` (m): a rollout ends once its jam reaches it.
    A path phi cannot settle or step reads failed (final_boxes None, jam None). Once the
    `time.monotonic` ``deadline`` has passed, no phi is built and no knot stepped: the paths
    not yet rolled out read `UNFINISHED`."""
    if past(deadline):
        return dict.fromkeys(paths, UNFINISHED)
    dyn = judge_dynamics(config)
    states = scene_box_states(world)
    first, *others = (np.asarray(q, float) for q in paths.values())
    if config.phi_judge.prune:
        kept = set(prune(world, first, states, dyn, config.world, "capsules",
                         tuple(others)).kept)
    else:
        kept = {b.name for b in world.boxes}
    out: dict[str, JudgedRollout] = {}
    todo = dict(paths)
    for round_ in range(dyn.prune_rounds + 1):
        if past(deadline):
            return {**out, **dict.fromkeys(todo, UNFINISHED)}
        spec = make_spec(world, [b.name for b in world.boxes if b.name in kept], states,
                         knot_time, dyn, config.world, "capsules")
        phi = build_phi(spec)
        in_one = config.phi_judge.stepping == "kept" and hasattr(phi, "keep_world")
        try:
            start = initial_state(spec.layout, first[0], states)
            x0 = phi.keep_world(start) if in_one else phi.settle(start)
        except (RuntimeError, ValueError):  # Drake's solver errors while settling
            return {**out, **dict.fromkeys(todo, JudgedRollout(None, None))}
        if not np.all(np.isfinite(x0)):  # the settle failed: nothing can be rolled out
            return {**out, **dict.fromkeys(todo, JudgedRollout(None, None))}
        out.update(_rollouts(phi, x0, todo, config.phi_judge, stop, deadline, in_one))
        touched = set().union(*(out[name].touched for name in todo))
        if not touched or round_ == dyn.prune_rounds:
            break
        kept |= touched
        todo = {name: q for name, q in todo.items() if out[name].touched}
    return {name: out[name] for name in paths}


def judge_dynamics(config: Config) -> DynamicsConfig:
    """phi's settings in the judge in phi: ``dynamics`` in ``phi_judge.engine`` at
    ``phi_judge.time_step``, read every ``phi_judge.sample_steps`` steps, its boxes sleeping
    where ``phi_judge.sleep``."""
    judge = config.phi_judge
    return replace(config.dynamics, engine=judge.engine, mujoco_time_step=judge.time_step,
                   mujoco_sample_steps=judge.sample_steps, mujoco_sleep=judge.sleep)


def _rollouts(phi, x0: np.ndarray, paths: dict[str, np.ndarray], phi_judge: PhiJudgeConfig,
              stop: float | None, deadline: float | None = None,
              kept: bool = False) -> dict[str, JudgedRollout]:
    """`_judged_rollout` (``kept``: `_kept_rollout`, phi's kept world) of every path, in
    ``phi_judge.threads`` threads where phi can be cloned (MuJoCo), each thread stepping its
    own clone: the same rollouts as in turn."""
    hold = phi_judge.hold_knots
    threads = min(phi_judge.threads, len(paths))
    if kept:
        def one(twin, q):
            return _kept_rollout(twin, np.asarray(q, float), hold, stop, deadline)
    else:
        def one(twin, q):
            return _judged_rollout(twin, x0, np.asarray(q, float), hold, stop, deadline)
    if threads <= 1 or not hasattr(phi, "clone"):
        return {name: one(phi, q) for name, q in paths.items()}
    idle = queue.SimpleQueue()
    for twin in [phi, *(phi.clone() for _ in range(threads - 1))]:
        idle.put(twin)

    def roll(q: np.ndarray) -> JudgedRollout:
        twin = idle.get()
        try:
            return one(twin, q)
        finally:
            idle.put(twin)

    with ThreadPoolExecutor(threads) as executor:
        return dict(zip(paths, executor.map(roll, paths.values()), strict=True))


def _judged_rollout(phi, x0: np.ndarray, q: np.ndarray, hold_knots: int,
                    stop: float | None, deadline: float | None = None) -> JudgedRollout:
    """One path from x0 (its arm set to q[0]) through its knots and the hold, phi(x, u) knot
    by knot; `UNFINISHED` once the `time.monotonic` ``deadline`` has passed before a knot."""
    state = {"x": x0}
    run = _stepped_knots(phi, x0, _held(q, hold_knots), bool(phi.spec.frozen), state)
    return _read_run(phi, run, lambda: state["x"], stop, deadline)


def _kept_rollout(phi, q: np.ndarray, hold_knots: int, stop: float | None,
                  deadline: float | None = None) -> JudgedRollout:
    """`_judged_rollout` in phi's kept world (`MujocoPhi.kept_knots`: the world settled once,
    never reset between knots)."""
    run = phi.kept_knots(_held(q, hold_knots), trace=bool(phi.spec.frozen))
    return _read_run(phi, run, lambda: phi.kept_state, stop, deadline)


def _held(q: np.ndarray, hold_knots: int) -> np.ndarray:
    """The knots of a path (T + 1, 8) with its last one repeated ``hold_knots`` times."""
    return np.array([*q, *([q[-1]] * hold_knots)])


def _stepped_knots(phi, x0: np.ndarray, knots: np.ndarray, trace: bool, state: dict):
    """phi(x, u) from x0 (its arm set to knots[0]) through the later knots, yielding each
    knot's (jam per kept box, m; edges, with ``trace``) as `MujocoPhi.kept_knots` does, the
    state after it in ``state["x"]``; a Drake solver error or a state out of phi's layout
    yields NaN jams and ends."""
    x = x0.copy()
    x[:ARM_DIM] = knots[0]
    for u in knots[1:]:
        try:
            if trace:
                x, edges, jam = phi.step_traced_jam(x, u)
            else:
                (x, jam), edges = phi.step_jam(x, u), set()
        except (RuntimeError, ValueError):  # Drake's solver errors while stepping
            yield np.full(phi.layout.num_boxes, np.nan), set()
            return
        if not phi.layout.is_state(x):
            yield jam * np.nan, edges
            return
        state["x"] = x
        yield jam, edges


def _read_run(phi, run, final, stop: float | None, deadline: float | None) -> JudgedRollout:
    """The `JudgedRollout` of a run of knots (an iterator of (jam, edges) per knot, NaN jams
    for a failed one), ``final()`` its last state: the largest knot's jam, the frozen boxes
    reached, stopped once the jam reaches ``stop``; `UNFINISHED` once the ``deadline`` has
    passed before a knot."""
    touched = set()
    worst = 0.0
    try:
        while True:
            if past(deadline):
                return UNFINISHED
            try:
                jam, edges = next(run)
            except StopIteration:
                break
            touched |= phi.frozen_touched(edges)
            if not np.all(np.isfinite(jam)):
                return JudgedRollout(None, None, touched=frozenset(touched))
            worst = max(worst, float(jam.max(initial=0.0)))
            if stop is not None and worst >= stop:
                return JudgedRollout(None, worst, True, frozenset(touched))
    finally:
        run.close()
    boxes = phi.layout.boxes(final()).copy()
    return JudgedRollout(dict(zip(phi.layout.box_names, boxes, strict=True)), worst,
                         touched=frozenset(touched))


def judge_paths(scene: Scene, paths: dict[str, np.ndarray], times: np.ndarray, config: Config,
                geometry: ArmGeometry, pool=None, members: Sequence[int] | None = None,
                complete: bool = True, deadline: float | None = None) -> dict[str, PhiVerdict]:
    """Each knot path's (T + 1, 8 each, knots at ``times`` s) verdict over phi's ensemble members
    ``members`` (default: 0 .. ``phi_judge.members`` - 1); all paths of one call meet the same
    members, each member's phi pruned for all of them and rolled out from each path's own start
    (`judged_rollouts`). ``complete=False`` reads the same classes with less work: a path out
    of the limits is not rolled out, a rollout stops once its jam reads a kinematic failure
    (its findings then say ``stopped`` and hold no box fates), and the press is not measured.
    ``pool`` (a `phi.workers.WorkerPool`): the members are rolled out in its workers, one
    member a task (the same verdicts; each worker builds its own arm). ``geometry``: the
    capsule arm with the boxes at rest (`PlanningContext.arm`). ``deadline`` (a
    `time.monotonic` value): no knot is stepped after it, and a path not rolled out in every
    member by then has no verdict (it is left out of the answer)."""
    if past(deadline):
        return {}
    checks = {name: plan_checks(scene, geometry, q, times, config, press=complete)
              for name, q in paths.items()}
    order = list(range(config.phi_judge.members) if members is None else members)
    jobs = [(scene, paths, np.asarray(times, float), config, checks, m, complete, deadline)
            for m in order]
    if pool is None:
        per_member = [_member_found(job, geometry) for job in jobs]
    else:
        per_member = pool.run(_member_task, jobs)
    return {name: PhiVerdict.from_findings([found[name] for found in per_member], config)
            for name in paths if all(name in found for found in per_member)}


def _member_task(job) -> dict[str, PhiFindings]:
    """`_member_found` in a worker process, with the worker's own capsule arm at rest."""
    scene, config, deadline = job[0], job[3], job[-1]
    if past(deadline):
        return {}
    return _member_found(job, PlanningContext(scene, config).arm())


def _member_found(job, geometry: ArmGeometry) -> dict[str, PhiFindings]:
    """One member's findings of every path it finished, ``geometry`` the capsule arm with
    the boxes at rest."""
    scene, paths, times, config, checks, member, complete, deadline = job
    if past(deadline):
        return {}
    decided = set() if complete else {name for name, (limit, _) in checks.items() if limit}
    stop = None if complete else config.phi_judge.jam_depth
    world, cfg = member_world(scene, config, member)
    rolled = judged_rollouts(world, {n: q for n, q in paths.items() if n not in decided}, cfg,
                             float(np.diff(times[:2])[0]), stop, deadline)
    out = {name: PhiFindings(*checks[name], jam=None, stopped=True) for name in decided}
    for name, r in rolled.items():
        if r.unfinished:
            continue
        if r.stopped:
            out[name] = PhiFindings(*checks[name], jam=r.jam, stopped=True)
        else:
            out[name] = member_findings(scene, geometry, paths[name], r, *checks[name],
                                        config.evaluation)
    return {name: out[name] for name in paths if name in out}
