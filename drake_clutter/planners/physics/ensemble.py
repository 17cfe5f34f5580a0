"""phi's ensemble (beyond the paper): a knot path scored over K perturbed rollouts, not one.

One phi rollout is chaotic at the scale of a planner's steps (moving every control by eps moves
toppling boxes by 1e5-1e6 eps) and mis-models Bullet's contact, so a single rollout's objective
ranks plans little better than a coin. Following randomized smoothing of contact dynamics (Suh,
Pang, Tedrake, RA-L 2022) and stochastic trajectory optimisation over noisy rollouts in shelf
clutter (Papallas, Cohn, Dogar, RA-L 2020), a path is scored in K members: member 0 is the scene
as it is; member k >= 1 is the scene with every box moved and its mass and friction scaled
(`scene.perturbation.perturb_boxes`, seeded with ``[ensemble.seed, k]``); member 1 pairs
friction as Bullet does when ``ensemble.bullet_friction_member`` is set. Every path scored in
one call meets the same members (common random numbers). The score of a path is a risk measure
of its K objectives (``ensemble.risk``).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, replace

import numpy as np

from drake_clutter.common.config import Config, EnsembleConfig
from drake_clutter.phi.derivatives import arm_touches_box
from drake_clutter.phi.state import ARM_DIM
from drake_clutter.planners.physics.stage import HoldTail, StageProblem, stage_problem
from drake_clutter.scene.perturbation import BoxPerturbation, perturb_boxes
from drake_clutter.scene.scenes import Scene
from drake_clutter.solvers import ilqr


def member_world(scene: Scene, config: Config, member: int) -> tuple[Scene, Config]:
    """Member ``member``'s scene and configuration (0: both unchanged; see the module
    docstring)."""
    if member == 0:
        return scene, config
    ens = config.ensemble
    ranges = BoxPerturbation(ens.position, ens.yaw, ens.mass, ens.friction)
    world = perturb_boxes(scene, ranges, [ens.seed, member])
    if member == 1 and ens.bullet_friction_member:
        config = replace(config, world=replace(config.world, friction_as_bullet=True))
    return world, config


def risk_score(values: Sequence[float], ens: EnsembleConfig) -> float:
    """The ensemble score of one path from its members' objectives (inf where any member's
    phi failed): their mean, mean + risk_weight x std (population), or the mean of the worst
    ceil(cvar_fraction K)."""
    v = np.asarray(values, float)
    if not np.all(np.isfinite(v)):
        return float("inf")
    if ens.risk == "mean":
        return float(v.mean())
    if ens.risk == "mean_std":
        return float(v.mean() + ens.risk_weight * v.std())
    worst = max(1, int(np.ceil(ens.cvar_fraction * v.size)))
    return float(np.sort(v)[-worst:].mean())


@dataclass(frozen=True)
class MemberRollout:
    """One path in one member: its full-stage terms (None where phi failed), every kept
    box's 13-number state (quaternion wxyz, position in W (m), angular and linear velocity)
    at the end of the hold tail (None where phi failed), and whether the arm or a kept box
    reached a box phi holds frozen (the score then misses that box's response); ``jam``, when
    asked for, the largest knot's jam measure over the path and the hold tail (m, `phi.jam`)."""

    terms: dict[str, float] | None
    final_boxes: dict[str, np.ndarray] | None
    reached_frozen: bool = False
    jam: float | None = None


FAILED = MemberRollout(None, None)


@contextmanager
def member_problems(scene: Scene, paths: dict[str, np.ndarray], config: Config, pool=None,
                    knot_time: float | None = None, approach=None,
                    extra_margin: float = 0.0, aim_T=None
                    ) -> Iterator[list[StageProblem | None]]:
    """Each member's full-stage `StageProblem` (capsule arm, hold tail; None where phi cannot
    settle the member's scene), its phi pruned for all ``paths`` (T + 1, 8 each, one start)
    with ``dynamics.prune_margin`` widened by ``extra_margin`` (m), c_grasp aimed at
    ``aim_T`` (`stage.stage_problem`); all closed on leaving.
    Paths scored in them (`score_in_members`) meet the same phis, whose step caches serve the
    steps paths share."""
    first, *others = paths.values()
    with ExitStack() as stack:
        problems: list[StageProblem | None] = []
        for member in range(config.ensemble.members):
            world, cfg = member_world(scene, config, member)
            if extra_margin:
                cfg = replace(cfg, dynamics=replace(
                    cfg.dynamics, prune_margin=cfg.dynamics.prune_margin + extra_margin))
            try:
                problems.append(stack.enter_context(stage_problem(
                    world, first, cfg, "capsules", pool, knot_time, approach,
                    also=tuple(others), aim_T=aim_T)))
            except (RuntimeError, ValueError):  # Drake's solver errors while settling
                problems.append(None)
        yield problems


def score_in_members(problems: list[StageProblem | None], paths: dict[str, np.ndarray],
                     config: Config) -> tuple[dict[str, float], dict[str, list[float | None]],
                                              dict[str, bool]]:
    """Each path's ensemble score (`risk_score`) in the members' ``problems``, its members'
    objectives (None where phi failed) and whether any member's rollout reached a frozen
    box."""
    totals: dict[str, list[float | None]] = {name: [] for name in paths}
    frozen = dict.fromkeys(paths, False)
    for problem in problems:
        for name, q in paths.items():
            r = FAILED if problem is None else _rollout_or_failed(problem, q)
            totals[name].append(None if r.terms is None else float(sum(r.terms.values())))
            frozen[name] |= r.reached_frozen
    scores = {name: risk_score([np.inf if v is None else v for v in values], config.ensemble)
              for name, values in totals.items()}
    return scores, totals, frozen


def member_rollouts(scene: Scene, paths: dict[str, np.ndarray], config: Config, member: int,
                    pool=None, knot_time: float | None = None, approach=None,
                    jam: bool = False) -> dict[str, MemberRollout]:
    """Each knot path (T + 1, 8) rolled out in member ``member``'s phi, pruned for all
    ``paths`` together, priced by the full stage's objective per Table I term (capsule arm,
    hold tail), with ``jam`` also its jam measure (one more rollout); `FAILED` for a path phi
    cannot roll out (the others are still priced), and for every path where phi cannot even
    settle the member's scene."""
    world, cfg = member_world(scene, config, member)
    first, *others = paths.values()
    try:
        with stage_problem(world, first, cfg, "capsules", pool, knot_time, approach,
                           also=tuple(others)) as problem:
            return {name: _rollout_or_failed(problem, q, jam) for name, q in paths.items()}
    except (RuntimeError, ValueError):  # Drake's solver errors while settling
        return {name: FAILED for name in paths}


def _rollout_or_failed(problem: StageProblem, q: np.ndarray, jam: bool = False) -> MemberRollout:
    try:
        return _rollout(problem, q, jam)
    except (RuntimeError, ValueError):  # Drake's solver errors while stepping
        return FAILED


def _rollout(problem: StageProblem, q: np.ndarray, jam: bool = False) -> MemberRollout:
    zs = ilqr.rollout(problem.augmented, path_start(problem, q), q[1:])
    if not np.all(np.isfinite(zs)):
        return FAILED
    terms = {k: float(v) for k, v in problem.objective.terms(zs, q[1:]).items()}
    layout = problem.dynamics.layout
    steps = [(z[:layout.nx], u) for z, u in zip(zs[:-1], q[1:], strict=True)]
    x_end = zs[-1][:layout.nx]
    if isinstance(problem.objective, HoldTail):
        ys, _, holds = problem.objective.tail(zs[-1])
        x_end = ys[-1]
        steps += list(zip(ys[:-1], holds, strict=True))
    frozen = _reached_frozen(problem, steps)
    worst = _worst_jam(problem, steps) if jam else None
    if not np.all(np.isfinite(x_end)):
        return MemberRollout(terms, None, frozen, worst)
    return MemberRollout(terms, dict(zip(layout.box_names, layout.boxes(x_end).copy(),
                                         strict=True)), frozen, worst)


def path_start(problem: StageProblem, q: np.ndarray) -> np.ndarray:
    """The problem's start z0 with the arm (and the previous knot's arm) at the path's first
    knot q[0] (8,): paths of one problem may start apart (other grasp heights); the boxes
    stay where phi settled them."""
    z0 = problem.z0.copy()
    z0[:ARM_DIM] = q[0]
    z0[problem.dynamics.layout.nx:] = q[0]
    return z0


def _worst_jam(problem: StageProblem, steps) -> float:
    """The largest knot's jam measure (m, any kept box) over the (x, u) steps."""
    phi = problem.dynamics.phi
    worst = 0.0
    for x, u in steps:
        if np.all(np.isfinite(x)):
            worst = max(worst, float(np.nan_to_num(phi.step_jam(x, u)[1]).max(initial=0.0)))
    return worst


def _reached_frozen(problem: StageProblem, steps) -> bool:
    """Whether any of the (x, u) steps, all taken already (phi's step cache answers), reached
    a frozen box."""
    dynamics = problem.dynamics
    if not dynamics.spec.frozen:
        return False
    return any(dynamics.phi.frozen_touched(dynamics.edges(x, u))
               for x, u in steps if np.all(np.isfinite(x)))


def first_contact_knot(problem: StageProblem | None, q: np.ndarray) -> int | None:
    """The first knot t whose phi step (to knot t + 1) has the arm touching a kept box when
    the path q (T + 1, 8) is rolled out in ``problem``; None without contact (or problem)."""
    if problem is None:
        return None
    zs = ilqr.rollout(problem.augmented, problem.z0, q[1:])
    nx = problem.dynamics.layout.nx
    for t in range(len(q) - 1):
        if not np.all(np.isfinite(zs[t])):
            return None
        if arm_touches_box(problem.dynamics.edges(zs[t][:nx], q[t + 1])):
            return t
    return None


def ensemble_scores(scene: Scene, paths: dict[str, np.ndarray], config: Config, pool=None,
                    knot_time: float | None = None, approach=None, aim_T=None
                    ) -> tuple[dict[str, float], dict[str, list[float | None]]]:
    """Each path's ensemble score (`risk_score` over ``ensemble.members`` members, each phi
    pruned for all ``paths``, c_grasp aimed at ``aim_T``) and its members' objectives (None
    where phi failed)."""
    with member_problems(scene, paths, config, pool, knot_time, approach,
                         aim_T=aim_T) as problems:
        scores, totals, _ = score_in_members(problems, paths, config)
    return scores, totals

