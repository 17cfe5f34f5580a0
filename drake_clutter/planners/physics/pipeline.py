"""The physics-based planner of Sec. V on each baseline candidate (`optimise_candidate`):

0. ``height`` (ours): the start is the first of the baseline's straight paths at the heights and
   yaws of ``physics.grasp_heights`` / ``approach_offsets`` clear of the boxes
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

Each phi stage (`stage.stage_problem`) prunes the boxes to the path, settles them under the arm,
adds the held knots after Delta and runs iLQR on z = [x, q^(t-1)] in tangent coordinates
(`ilqr.solve`, or the B-spline controls of `spline.solve_spline` with ``controls`` "spline");
controls are bounded by the PR2's joint limits and the gripper's [0, 0.09] m. With the default
``iterations`` 0 no phi stage runs.

Failure modes: a phi stage whose start phi cannot simulate restarts from the start path
(``started_from``); any other failure is a candidate with status ``optimisation_failed`` and a
reason, never an exception. ``physics.time_budget`` (s) cuts solvers at the deadline and leaves
out the phi stages and ``select`` once it has passed (``details["time_budget"]``).

Returns a `trajectory.Candidate` (planner "physics"): ``details`` per stage (cost and term
history, iterations, stop reason), ``timings`` (s per stage) and ``details["feedback"]`` (the
last phi stage's gains K_t, k_t and the kept boxes they refer to). How the stages came to be:
docs/physics_planner.md and docs/log/physics_planner.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from drake_clutter.common.config import Config, check_config
from drake_clutter.phi.state import ARM_DIM
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.approach import grasp_offset
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.physics.grasp_height import choose_height
from drake_clutter.planners.physics.objective import (
    KinematicObjective,
    PhysicsObjective,
    max_steps,
    pregrasp_aim,
)
from drake_clutter.planners.physics.stage import AugmentedPhi, stage_problem
from drake_clutter.planners.selection import selection_score
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import Scene
from drake_clutter.solvers import ilqr, spline
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory, spline_basis

ROLL_BOUND = 4 * np.pi  # rad, bound of the continuous rolls' controls; ours: two turns either
# way is more than any reach needs, and a bound keeps a bad feedback gain from sending phi a
# control of 1e200 rad (seen on the default scene)


GRIPPER = ARM_DIM - 1  # the control's column of the gripper opening (m)


class PhiFailure(RuntimeError):
    """phi could not simulate a stage's initial path."""


class KinematicArm:
    """The arm alone as iLQR dynamics: state q^t (8), control q^(t+1), x_{t+1} = u_t."""

    def step(self, t: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The next configuration is the control."""
        return np.array(u, dtype=float)

    def linearize(self, xs: np.ndarray, us: np.ndarray):
        """A = 0, B = I at every interval."""
        T, n = len(us), xs.shape[1]
        return np.zeros((T, n, n)), np.repeat(np.eye(n)[None], T, axis=0)


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
    time.perf_counter() value (s) past which the solver stops with its best path so far."""
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


def _stage_record(result: ilqr.ILQRResult, seconds: float, extra: dict | None = None) -> dict:
    return {"iterations": result.iterations, "stop_reason": str(result.stop_reason),
            "seconds": seconds, "cost_history": [float(c) for c in result.cost_history],
            "term_history": [{k: float(v) for k, v in h.items()} for h in result.term_history],
            "timings": dict(result.timings), "log": _json_log(result.log), **(extra or {})}


def _json_log(log: list[dict]) -> list[dict]:
    return [{k: (v if isinstance(v, bool) else float(v)) for k, v in e.items()} for e in log]


def preprocess(context: PlanningContext, q_init: np.ndarray, deadline: float | None = None
               ) -> tuple[np.ndarray, ilqr.ILQRResult]:
    """Sec. V-A on a knot path (T + 1, 8): the path with less box contact (the capsule arm,
    the boxes at rest), and the solver's result (stopped at ``deadline``, see
    `solver_settings`)."""
    scene, config, geometry = context.scene, context.config, context.arm()
    objective = KinematicObjective(
        geometry, config.physics, "pre", config.baseline.d_safe, scene.target,
        p_pregrasp=geometry.tool(q_init[-1])[0], w_static_hull=config.baseline.w_static_hull,
        w_vel=config.baseline.w_vel)
    keep = config.physics.pre_keep_pregrasp
    bounds = knot_bounds(q_init, last_knot=keep, gripper=keep)
    result = ilqr.solve(KinematicArm(), objective, q_init[0], q_init[1:],
                        solver_settings(config, config.physics.pre_iterations, bounds=bounds,
                                        deadline=deadline))
    return result.xs, result


def postprocess(context: PlanningContext, q_ref: np.ndarray, deadline: float | None = None
                ) -> tuple[np.ndarray, ilqr.ILQRResult]:
    """Sec. V-B on a knot path (T + 1, 8): c_static in the ``physics.post_variant`` geometry,
    c_match and c_match_vel to ``q_ref`` (stopped at ``deadline``, see `solver_settings`)."""
    scene, config = context.scene, context.config
    geometry = context.arm(config.physics.post_variant)
    objective = KinematicObjective(geometry, config.physics, "post", config.baseline.d_safe,
                                   scene.target, q_ref=q_ref,
                                   knot_time=config.baseline.knot_time)
    keep = config.physics.post_keep_end
    bounds = knot_bounds(q_ref, last_knot=keep, gripper=keep)
    result = ilqr.solve(KinematicArm(), objective, q_ref[0], q_ref[1:],
                        solver_settings(config, config.physics.post_iterations, bounds=bounds,
                                        deadline=deadline))
    return result.xs, result


def physics_stage(context: PlanningContext, q: np.ndarray, variant: str, iterations: int,
                  pool: WorkerPool | None = None, times: np.ndarray | None = None,
                  alternatives: tuple[np.ndarray, ...] = (), min_opening: float | None = None,
                  deadline: float | None = None, aim_T: np.ndarray | None = None
                  ) -> tuple[np.ndarray, ilqr.ILQRResult, dict]:
    """iLQR through phi (``variant`` arm) from the knot path ``q`` (T + 1, 8) at ``times`` (s;
    default: ``baseline.knot_time`` apart): the new path, the solver's result and what the
    stage used (kept boxes, pruning, phi statistics). With ``alternatives`` (paths of the same
    shape and start), iLQR starts from whichever of ``q`` and them has the lowest objective in
    this stage's phi (pruned for all of them); info's ``start_objectives`` lists them.
    ``min_opening``: the last knot's least gripper opening
    (m, `knot_bounds`); ``deadline``: see `solver_settings`; ``aim_T``: c_grasp's point in
    the target's frame (`objective.pregrasp_aim`; default: ``q``'s last knot's)."""
    config = context.config
    knot_time = _knot_time(times, config)
    with stage_problem(context, q, variant, pool, knot_time, also=tuple(alternatives),
                       aim_T=aim_T) as problem:
        augmented, objective, z0 = problem.augmented, problem.objective, problem.z0
        starts = [q, *alternatives]
        basis = None
        if config.physics.controls == "spline":
            basis = spline_basis(len(q), config.physics.control_points,
                                 config.baseline.opt_spline_order)
            starts = [spline_path(basis, path) for path in starts]
        values = [_path_objective(augmented, objective, z0, path) for path in starts]
        if not np.any(np.isfinite(values)):
            raise PhiFailure("phi failed on the initial rollout")
        q = starts[int(np.argmin(values))]
        bounds = knot_bounds(q, min_final_opening=min_opening)
        settings = solver_settings(config, iterations, knot_time, bounds, deadline)
        if basis is None:
            result = ilqr.solve(augmented, objective, z0, q[1:], settings,
                                difference=augmented.difference)
        else:
            result = spline.solve_spline(augmented, objective, z0, q[1:], basis, q[0],
                                         settings, difference=augmented.difference)
        info = {"kept_boxes": list(augmented.layout.box_names),
                "pruning": problem.report.summary(),
                "phi_failures": problem.dynamics.phi.failures,
                "autodiff_fallbacks": problem.dynamics.autodiff_fallbacks,
                "start_objectives": [float(v) for v in values]}
    return np.vstack([q[:1], result.us]), result, info


def spline_path(basis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The knot path (T + 1, 8) nearest ``q`` (least squares) among the B-splines of ``basis``
    (T + 1, P + 1) that start at q[0]; a path that already is one comes back unchanged."""
    controls = spline.SplineControls(basis, q[0])
    return np.vstack([q[:1], controls.controls(controls.fit(q[1:]))])


def path_terms(dynamics: AugmentedPhi, objective: PhysicsObjective, z0: np.ndarray,
               q: np.ndarray) -> dict[str, float] | None:
    """A phi stage's objective per Table I term for the knot path ``q`` (T + 1, 8) rolled out
    from z0; None where phi's rollout is not finite."""
    zs = ilqr.rollout(dynamics, z0, q[1:])
    if not np.all(np.isfinite(zs)):
        return None
    return {k: float(v) for k, v in objective.terms(zs, q[1:]).items()}


def _path_objective(dynamics: AugmentedPhi, objective: PhysicsObjective, z0: np.ndarray,
                    q: np.ndarray) -> float:
    """The stage's objective of the knot path ``q`` rolled out from z0 (inf where phi fails)."""
    terms = path_terms(dynamics, objective, z0, q)
    return float("inf") if terms is None else float(sum(terms.values()))


def _knot_time(times: np.ndarray | None, config: Config) -> float:
    """The knots' spacing (s): of ``times``, else ``baseline.knot_time``."""
    return float(np.diff(times[:2])[0]) if times is not None else config.baseline.knot_time


def select_path(context: PlanningContext, paths: dict[str, np.ndarray], pool=None,
                times: np.ndarray | None = None, aim_T: np.ndarray | None = None
                ) -> tuple[str, dict]:
    """The name of the knot path (each (T + 1, 8), one start) with the lowest objective of the
    full stage (capsule arm, hold tail) in one phi pruned for all ``paths``, and what was
    measured: each path's objective (None where phi fails) and the pruning. Ties go to the
    earlier name; when phi fails on every path, the first. ``aim_T``: c_grasp's point in the
    target's frame (default: the first path's last knot's)."""
    knot_time = _knot_time(times, context.config)
    names = list(paths)
    first, *others = (paths[n] for n in names)
    with stage_problem(context, first, "capsules", pool, knot_time, also=tuple(others),
                       aim_T=aim_T) as problem:
        values = {n: _path_objective(problem.augmented, problem.objective, problem.z0,
                                     paths[n]) for n in names}
        pruning = problem.report.summary()
    chosen = min(names, key=lambda n: (values[n], names.index(n)))
    finite = {n: (v if np.isfinite(v) else None) for n, v in values.items()}
    return chosen, {"objectives": finite, "chosen": chosen, "pruning": pruning}


def _phi_stage_or_restart(context: PlanningContext, paths: tuple[np.ndarray, np.ndarray],
                          variant: str, iterations: int, pool, times,
                          alternatives: tuple[np.ndarray, ...] = (),
                          deadline: float | None = None, aim_T: np.ndarray | None = None):
    """`physics_stage` from ``paths[0]`` (or the best of ``alternatives``, see there); if phi
    cannot simulate any of them, from ``paths[1]`` (the baseline's path: phi failed on paths
    the pre-processing or sphere stage produced with the hydroelastic phi, measured on
    fig7); its info says which."""
    opening = (float(paths[1][-1, GRIPPER]) if context.config.physics.keep_open else None)
    try:
        q, result, info = physics_stage(context, paths[0], variant, iterations, pool,
                                        times, alternatives, opening, deadline, aim_T=aim_T)
        best = int(np.argmin(info["start_objectives"]))
        return q, result, {**info, "started_from": "previous stage" if best == 0 else
                           f"alternative {best}"}
    except PhiFailure as exc:
        if np.array_equal(paths[0], paths[1]):
            raise
        q, result, info = physics_stage(context, paths[1], variant, iterations, pool,
                                        times, min_opening=opening, deadline=deadline,
                                        aim_T=aim_T)
        return q, result, {**info, "started_from": f"baseline ({exc})"}


@dataclass
class Budget:
    """One initialization's wall-time budget (``physics.time_budget``, s; None: no limit),
    counted from its creation, and the stages it cut short or left out."""

    seconds: float | None
    start: float = field(default_factory=time.perf_counter)
    stopped: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    forecast: float = 0.0  # s a phi world's set-up and one iteration took (`learn`)

    @property
    def deadline(self) -> float | None:
        """The time.perf_counter() value (s) at which the budget is spent; None: never."""
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

    def note(self, stage: str, result: ilqr.ILQRResult) -> None:
        """Records ``stage`` as cut short when its solver stopped at the deadline."""
        if result.stop_reason == ilqr.StopReason.TIME_BUDGET:
            self.stopped.append(stage)

    def record(self, returned: str) -> dict:
        """What the candidate's details keep: the budget (s), the time taken ("wall_time",
        s: an experiment store moves it to the unit's timings), whether it was spent, the
        stages cut short and left out, and the path returned."""
        return {"budget": self.seconds, "wall_time": time.perf_counter() - self.start,
                "spent": bool(self.stopped or self.skipped), "stopped": list(self.stopped),
                "skipped": list(self.skipped), "returned": returned}


def _failed(candidate: Candidate, reason: str, timings: dict, details: dict) -> Candidate:
    return Candidate(candidate.alpha, CandidateStatus.OPTIMISATION_FAILED, reason,
                     candidate.trajectory, planner="physics", timings=timings, details=details)


def optimise_candidate(context: PlanningContext, candidate: Candidate,
                       pool: WorkerPool | None = None) -> Candidate:
    """Sec. V on one baseline candidate (module docstring) in the scene's planning
    ``context``; a non-"ok" candidate comes back as it is, relabelled planner "physics"."""
    if not candidate.ok:
        return replace(candidate, planner="physics",
                       reason=f"no initialization: {candidate.reason or candidate.status}")
    scene, config = context.scene, context.config
    cfg = config.physics
    budget = Budget(cfg.time_budget)
    timings, details = {}, {"stages": {}, "initialization": candidate.planner}
    if cfg.grasp_heights or cfg.approach_offsets:
        tic = time.perf_counter()
        try:
            candidate, details["grasp_height"] = choose_height(context, candidate)
        except (RuntimeError, ValueError) as exc:  # Drake or numerical errors: keep the start
            details["grasp_height"] = {"error": str(exc)}
        timings["height"] = time.perf_counter() - tic
    details["start_score"] = selection_score("baseline", candidate.details, config.baseline)
    q = baseline_q = np.array(candidate.trajectory.q, dtype=float)
    # c_grasp aims where the start path's pads end (its pre-grasp), carried by the target.
    aim_T = pregrasp_aim(context.arm(), baseline_q[-1], scene.target,
                         grasp_offset(config.baseline))
    tic = time.perf_counter()
    try:
        q, result = preprocess(context, q, budget.deadline)
    except (RuntimeError, ValueError) as exc:  # Drake or numerical errors
        timings["pre"] = time.perf_counter() - tic
        return _failed(candidate, f"pre stage: {exc}", timings, details)
    timings["pre"] = time.perf_counter() - tic
    budget.note("pre", result)
    details["stages"]["pre"] = _stage_record(result, timings["pre"])
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
            q, result, info = _phi_stage_or_restart(context, (q, baseline_q), variant,
                                                    iterations, pool, candidate.trajectory.times,
                                                    others, budget.deadline, aim_T)
        except (RuntimeError, ValueError) as exc:  # PhiFailure, Drake or numerical errors
            timings[name] = time.perf_counter() - tic
            return _failed(candidate, f"{name} stage: {exc}", timings, details)
        timings[name] = time.perf_counter() - tic
        details["stages"][name] = _stage_record(result, timings[name], info)
        budget.note(name, result)
        budget.learn(details["stages"][name])
        last = (result, info)
    tic = time.perf_counter()
    try:
        q, result = postprocess(context, q, budget.deadline)
    except (RuntimeError, ValueError) as exc:  # Drake or numerical errors
        timings["post"] = time.perf_counter() - tic
        return _failed(candidate, f"post stage: {exc}", timings, details)
    timings["post"] = time.perf_counter() - tic
    details["stages"]["post"] = _stage_record(result, timings["post"])
    budget.note("post", result)
    chosen = "post"
    if cfg.select_in_phi and not budget.skip("select", phi=True):
        tic = time.perf_counter()
        paths = {"post": q, "pre": q_pre, "baseline": baseline_q}
        try:
            chosen, details["select"] = select_path(context, paths, pool,
                                                    candidate.trajectory.times, aim_T)
        except (RuntimeError, ValueError) as exc:  # Drake or numerical errors: keep post
            chosen, details["select"] = "post", {"chosen": "post", "error": str(exc)}
        q = paths[chosen]
        timings["select"] = time.perf_counter() - tic
    details["time_budget"] = budget.record(chosen)
    if last is not None:
        details["feedback"] = {"boxes": last[1]["kept_boxes"], "K": last[0].K.tolist(),
                               "k": last[0].k.tolist()}
    trajectory = Trajectory(candidate.trajectory.times.copy(), q)
    return Candidate(candidate.alpha, CandidateStatus.OK, "", trajectory, planner="physics",
                     timings=timings, details=details)




def plan_physics(scene: Scene, config: Config | None = None,
                 candidates: list[Candidate] | None = None,
                 pool: WorkerPool | None = None) -> list[Candidate]:
    """Sec. V on every candidate (default: `baseline.plan_baseline` of the scene), in order:
    one physics Candidate each. A shared worker pool for phi's derivatives is created (and
    closed) here unless one is passed in."""
    config = config or Config()
    check_config(config)
    if candidates is None:
        candidates = plan_baseline(scene, config.baseline)
    own = pool is None and config.dynamics.workers > 0
    pool = WorkerPool(config.dynamics.workers) if own else pool
    try:
        context = PlanningContext(scene, config)
        return [optimise_candidate(context, c, pool) for c in candidates]
    finally:
        if own:
            pool.close()


def stages_table(candidates: list[Candidate]) -> str:
    """A text table, one row per physics candidate: alpha, status, seconds per stage, the
    objective before and after the phi stages, and the reason."""
    rows = [f"{'alpha':>7} {'status':20} {'pre s':>6} {'sphere s':>8} {'full s':>7} "
            f"{'post s':>6} {'cost start':>11} {'cost end':>11}  reason"]
    for c in candidates:
        t, stages = c.timings, c.details.get("stages", {})
        phi = [stages[n] for n in ("sphere", "full") if n in stages]
        start = f"{phi[0]['cost_history'][0]:.4g}" if phi else "-"
        end = f"{phi[-1]['cost_history'][-1]:.4g}" if phi else "-"
        rows.append(f"{c.alpha:+7.3f} {c.status:20} {t.get('pre', 0.0):6.1f} "
                    f"{t.get('sphere', 0.0):8.1f} {t.get('full', 0.0):7.1f} "
                    f"{t.get('post', 0.0):6.1f} {start:>11} {end:>11}  {c.reason}")
    return "\n".join(rows)
