"""The physics-based planner of Sec. V on each baseline candidate (`optimise_candidate`):

0. ``height`` (ours): the start is the first of the baseline's straight paths at the heights and
   yaws of ``starts.grasp_heights`` / ``approach_offsets`` clear of the boxes
   (`grasp_height.choose_height`); it is the "baseline" path of every stage below.
1. ``pre`` (Sec. V-A): kinematic iLQR (state q^t, control q^(t+1)), the boxes fixed at rest:
   c_static_hull + c_dynamic + c_vel, c_grasp and c_grp_horiz at the end; the baseline's last
   knot and gripper openings kept as bounds (``pre_keep_pregrasp``).
2. ``sphere`` (Sec. V): ``sphere_iterations`` iLQR iterations through phi with the sphere gripper;
   the target is parked out of phi (``sphere_target``), c_static keeps the capsule gripper.
3. ``full`` (Sec. V): the remaining ``iterations - sphere_iterations`` with the capsule arm,
   started from the best in its phi of the sphere stage's, the pre-processed and the start path.
4. ``post`` (Sec. V-B): kinematic iLQR, c_static in the ``post_variant`` geometry + c_match +
   c_match_vel to the physics path, its last knot and openings kept (``post_keep_end``).
5. ``select`` (ours, ``select_in_phi``): the lowest objective of the full stage (hold tail
   included) in one phi pruned for the post-processed, pre-processed and start paths.

Where each stage lives: ``height`` in `grasp_height`, ``pre`` and ``post`` in `kinematic`, the
phi stages and ``select`` in `stage` (each phi stage prunes the boxes to the path, settles them
under the arm, adds the held knots after Delta and runs iLQR through phi); the controls' bounds
and the solver's settings of every stage in `limits`. With the default ``iterations`` 0 no phi
stage runs.

Failure modes: a phi stage whose start phi cannot simulate restarts from the start path
(``started_from``); any other failure is a candidate with status ``optimisation_failed`` and a
reason, never an exception. ``physics.time_budget`` (s) cuts solvers at the deadline and leaves
out the phi stages and ``select`` once it has passed (the record's ``time_budget``).

Returns a `trajectory.Candidate` (planner "physics"): ``details`` its `record.PhysicsRecord`
(per stage: cost and term history, iterations, stop reason; the last phi stage's gains K_t,
k_t and the kept boxes they refer to), ``timings`` (s per stage). How the stages came to be:
docs/physics_planner.md and docs/log/physics_planner.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from drake_clutter.common.config import Config, check_config
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.approach import grasp_offset
from drake_clutter.planners.baseline import BaselineRecord, plan_baseline
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import pregrasp_aim
from drake_clutter.planners.loop import refine_each
from drake_clutter.planners.physics.grasp_height import choose_height
from drake_clutter.planners.physics.kinematic import postprocess, preprocess
from drake_clutter.planners.physics.record import PhysicsRecord
from drake_clutter.planners.physics.stage import phi_stage_or_restart, select_path
from drake_clutter.scene.scenes import Scene
from drake_clutter.solvers import ilqr
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory


def _stage_record(result: ilqr.ILQRResult, seconds: float, extra: dict | None = None) -> dict:
    return {"iterations": result.iterations, "stop_reason": str(result.stop_reason),
            "seconds": seconds, "cost_history": [float(c) for c in result.cost_history],
            "term_history": [{k: float(v) for k, v in h.items()} for h in result.term_history],
            "timings": dict(result.timings), "log": _json_log(result.log), **(extra or {})}


def _json_log(log: list[dict]) -> list[dict]:
    return [{k: (v if isinstance(v, bool) else float(v)) for k, v in e.items()} for e in log]


@dataclass
class Budget:
    """One initialization's wall-time budget (``physics.time_budget``, s; None: no limit),
    counted from its creation, and the stages it cut short or left out."""

    seconds: float | None
    start: float = field(default_factory=time.monotonic)
    stopped: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    forecast: float = 0.0  # s a phi world's set-up and one iteration took (`learn`)
    longest_step: float = 0.0  # s: the longest indivisible step (a height's start, a phi
    # stage's set-up and first iteration), which no deadline can cut

    @property
    def deadline(self) -> float | None:
        """The time.monotonic() value (s) at which the budget is spent; None: never."""
        return None if self.seconds is None else self.start + self.seconds

    def skip(self, stage: str, phi: bool = False) -> bool:
        """True (and ``stage`` recorded as left out) when the budget is spent, or, for a
        stage that builds a phi (``phi``), would be before its set-up and first iteration
        end (the last phi stage's, `learn`)."""
        if ilqr.past(self.deadline, self.forecast if phi else 0.0):
            self.skipped.append(stage)
            return True
        return False

    def learn(self, record: dict) -> None:
        """Takes a phi stage's record (`_stage_record`) as the forecast of the next phi
        world: its time less all its iterations but one."""
        spent = sum(record["timings"].get(k, 0.0) for k in
                    ("linearize", "quadratize", "backward", "forward"))
        iterations = max(1, record["iterations"])
        self.forecast = max(0.0, record["seconds"] - spent * (iterations - 1) / iterations)
        self.longest_step = max(self.longest_step, self.forecast)

    def note(self, stage: str, result: ilqr.ILQRResult) -> None:
        """Records ``stage`` as cut short when its solver stopped at the deadline."""
        if result.stop_reason == ilqr.StopReason.TIME_BUDGET:
            self.stopped.append(stage)

    def record(self, returned: str) -> dict:
        """What the candidate's details keep: the budget (s), the time taken ("wall_time",
        s: an experiment store moves it to the unit's timings), whether it was spent, the
        stages cut short and left out, and the path returned."""
        return {"budget": self.seconds, "wall_time": time.monotonic() - self.start,
                "spent": bool(self.stopped or self.skipped), "stopped": list(self.stopped),
                "skipped": list(self.skipped), "returned": returned,
                "longest_step": self.longest_step}


def _failed(candidate: Candidate, reason: str, timings: dict,
            record: PhysicsRecord) -> Candidate:
    return Candidate(candidate.alpha, CandidateStatus.OPTIMISATION_FAILED, reason,
                     candidate.trajectory, planner="physics", timings=timings,
                     details=record.to_details())


def optimise_candidate(context: PlanningContext, candidate: Candidate, index: int | None = None,
                       pool: WorkerPool | None = None, started: float | None = None
                       ) -> Candidate:
    """Sec. V on one baseline candidate (module docstring; ``index``: its angle's, unused: the
    stages draw nothing at random) in the scene's planning ``context``; ``pool``: phi's
    workers; ``started``: the `time.monotonic` value its budget counts from (None: now). A
    non-"ok" candidate comes back as it is, relabelled planner "physics"."""
    if not candidate.ok:
        return replace(candidate, planner="physics",
                       reason=f"no initialization: {candidate.reason or candidate.status}")
    scene, config = context.scene, context.config
    cfg = config.physics
    budget = Budget(cfg.time_budget, start=started or time.monotonic())
    timings, record = {}, PhysicsRecord(initialization=candidate.planner)
    if config.starts.grasp_heights or config.starts.approach_offsets:
        tic = time.perf_counter()
        try:
            heights = Deadline(cfg.time_budget, start=budget.start)
            candidate, record.grasp_height = choose_height(context, candidate, heights)
            budget.skipped += heights.cut
            budget.longest_step = heights.longest_step
        except (RuntimeError, ValueError) as exc:  # Drake or numerical errors: keep the start
            record.grasp_height = {"error": str(exc)}
        timings["height"] = time.perf_counter() - tic
    record.start_score = BaselineRecord.from_details(candidate.details).score(config.baseline)
    q = baseline_q = np.array(candidate.trajectory.q, dtype=float)
    # c_grasp aims where the start path's pads end (its pre-grasp), carried by the target.
    aim_T = pregrasp_aim(context.arm(), baseline_q[-1], scene.target,
                         grasp_offset(config.baseline))
    tic = time.perf_counter()
    try:
        q, result = preprocess(context, q, budget.deadline)
    except (RuntimeError, ValueError) as exc:  # Drake or numerical errors
        timings["pre"] = time.perf_counter() - tic
        return _failed(candidate, f"pre stage: {exc}", timings, record)
    timings["pre"] = time.perf_counter() - tic
    budget.note("pre", result)
    record.stages["pre"] = _stage_record(result, timings["pre"])
    q_pre = q
    stages = (("sphere", "sphere_gripper", min(cfg.sphere_iterations, cfg.iterations)),
              ("full", "capsules", cfg.iterations - min(cfg.sphere_iterations, cfg.iterations)))
    last = None
    for name, variant, iterations in stages:
        if iterations <= 0 or budget.skip(name, phi=True):
            continue
        tic = time.perf_counter()
        try:
            # The full stage may start from the pre-processed or the baseline's path instead of
            # the sphere stage's: that stage's phi had no target and another gripper, and its
            # path knocked the target 14 cm away in the full stage's phi (fig6, measured).
            others = ()
            if name == "full":
                others = tuple(p for p in (q_pre, baseline_q)
                               if p is not q and not np.array_equal(p, q))
            q, result, info = phi_stage_or_restart(context, (q, baseline_q), variant,
                                                    iterations, pool, candidate.trajectory.times,
                                                    others, budget.deadline, aim_T)
        except (RuntimeError, ValueError) as exc:  # PhiFailure, Drake or numerical errors
            timings[name] = time.perf_counter() - tic
            return _failed(candidate, f"{name} stage: {exc}", timings, record)
        timings[name] = time.perf_counter() - tic
        record.stages[name] = _stage_record(result, timings[name], info)
        budget.note(name, result)
        budget.learn(record.stages[name])
        last = (result, info)
    tic = time.perf_counter()
    try:
        q, result = postprocess(context, q, budget.deadline)
    except (RuntimeError, ValueError) as exc:  # Drake or numerical errors
        timings["post"] = time.perf_counter() - tic
        return _failed(candidate, f"post stage: {exc}", timings, record)
    timings["post"] = time.perf_counter() - tic
    record.stages["post"] = _stage_record(result, timings["post"])
    budget.note("post", result)
    chosen = "post"
    if cfg.select_in_phi and not budget.skip("select", phi=True):
        tic = time.perf_counter()
        paths = {"post": q, "pre": q_pre, "baseline": baseline_q}
        try:
            chosen, record.select = select_path(context, paths, pool,
                                                    candidate.trajectory.times, aim_T)
        except (RuntimeError, ValueError) as exc:  # Drake or numerical errors: keep post
            chosen, record.select = "post", {"chosen": "post", "error": str(exc)}
        q = paths[chosen]
        timings["select"] = time.perf_counter() - tic
    record.time_budget = budget.record(chosen)
    if last is not None:
        record.feedback = {"boxes": last[1]["kept_boxes"], "K": last[0].K.tolist(),
                               "k": last[0].k.tolist()}
    trajectory = Trajectory(candidate.trajectory.times.copy(), q)
    return Candidate(candidate.alpha, CandidateStatus.OK, "", trajectory, planner="physics",
                     timings=timings, details=record.to_details())




def plan_physics(scene: Scene, config: Config | None = None,
                 candidates: list[Candidate] | None = None) -> list[Candidate]:
    """Sec. V on every candidate (default: `baseline.plan_baseline` of the scene), in order:
    one physics Candidate each (`loop.refine_each`: one worker pool for phi's derivatives,
    the first candidate's budget also paying for the planning worlds)."""
    config = config or Config()
    check_config(config)
    if candidates is None:
        candidates = plan_baseline(scene, config.baseline)
    return refine_each(scene, config, candidates, optimise_candidate)


def stages_table(candidates: list[Candidate]) -> str:
    """A text table, one row per physics candidate: alpha, status, seconds per stage, the
    objective before and after the phi stages, and the reason."""
    rows = [f"{'alpha':>7} {'status':20} {'pre s':>6} {'sphere s':>8} {'full s':>7} "
            f"{'post s':>6} {'cost start':>11} {'cost end':>11}  reason"]
    for c in candidates:
        t, stages = c.timings, PhysicsRecord.from_details(c.details).stages
        phi = [stages[n] for n in ("sphere", "full") if n in stages]
        start = f"{phi[0]['cost_history'][0]:.4g}" if phi else "-"
        end = f"{phi[-1]['cost_history'][-1]:.4g}" if phi else "-"
        rows.append(f"{c.alpha:+7.3f} {c.status:20} {t.get('pre', 0.0):6.1f} "
                    f"{t.get('sphere', 0.0):8.1f} {t.get('full', 0.0):7.1f} "
                    f"{t.get('post', 0.0):6.1f} {start:>11} {end:>11}  {c.reason}")
    return "\n".join(rows)
