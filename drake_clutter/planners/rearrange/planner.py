"""The rearrange planner (beyond the paper): make room, then reach.

Per approach angle it starts from the push planner's answer (its reach: straight or bent). The
region to clear is that reach's swept arm with the gripper open (`board.reach_region`); where
no box other than the target enters it by more than ``rearrange.deep``, the push answer is
returned unchanged. Otherwise the beam search (`search.search_room`) finds, geometry first, up
to ``rearrange.sequences`` sequences of at most ``max_moves`` pushes after which the region is
clear, each push with its joint path. Each sequence's plan (the pushes, then the reach) is
judged in phi beside the push answer (the judge in phi, the same members; every path held at
its first knot to the same length, so the members see the same end). The best sequence
replaces the push answer only where it reads P(success) >= ``rearrange.acceptance`` in the
members, beats the push answer's verdict there, and its classes also beat it on the
``phi_judge.veto_members`` members no one searched on; with ``rearrange.prefer_room`` a tie of
P(success) and the expected grade goes to the sequence (the push answer's reach is crowded).
The plan keeps the judge's joint and speed limits (`trajectory.plan_limit_violation`) and
clears the shelf (`clearance.dense_check`).

``rearrange.time_budget`` (s) bounds the work after the push planner; what it cut is in
``details["budget"]`` and the push answer stands. Deterministic: same scene, same plan.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.clearance import judge_feasible
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.loop import refine_each
from drake_clutter.planners.phi_judge import PhiVerdict, judge_paths
from drake_clutter.planners.rearrange.board import crowding, reach_region
from drake_clutter.planners.rearrange.record import PUSH, RearrangeRecord
from drake_clutter.planners.rearrange.search import State, search_room
from drake_clutter.planners.tool_path import ARM, approach_frame
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory

OPENING_KNOTS = 3  # knots over which the gripper opens at q0 before the reach (ours)


def plan_rearrange(scene: Scene, config: Config, start: list[Candidate]) -> list[Candidate]:
    """One "rearrange" Candidate per push candidate in ``start``, in order (module
    docstring; phi's members in ``dynamics.workers`` worker processes, 0: this one)."""
    return refine_each(scene, config, start, rearrange_candidate)


def rearrange_candidate(context: PlanningContext, candidate: Candidate, index: int,
                        pool=None, started: float | None = None) -> Candidate:
    """The rearrange planner on one push candidate (angle ``index``) in the scene's planning
    ``context``; ``started``: the `time.monotonic` value its budget counts from."""
    config, geometry = context.config, context.arm()
    deadline = Deadline(config.rearrange.time_budget, start=started or time.monotonic())
    push = dict(candidate.details)
    if not candidate.ok:
        return _unchanged(candidate, RearrangeRecord(why="no reach", push=push), deadline)
    reach = candidate.trajectory.q
    region = reach_region(reach, config.rearrange.region_knots)
    crowd = crowding(geometry, region, {}, config.rearrange.deep)
    if not crowd:
        return _unchanged(candidate, RearrangeRecord(why="clear", push=push), deadline)
    tic = time.perf_counter()
    frame = approach_frame(geometry, reach)
    rotation = geometry.tool_jacobian(reach[-1])[0].rotation().matrix()
    found = search_room(geometry, context.clearance, frame, region, reach[0], rotation, config,
                        deadline)
    timings = {"room": time.perf_counter() - tic}
    record = RearrangeRecord(why="no room", crowd=crowd, search=found.to_data(), push=push)
    plans = {f"room{i}": sequence_path(goal, reach) for i, goal in enumerate(found.goals)}
    plans = {n: q for n, q in plans.items() if judge_feasible(
        q, np.arange(len(q)) * config.baseline.knot_time, context.clearance, config)}
    if not plans:
        return _unchanged(candidate, record, deadline, timings)
    tic = time.perf_counter()
    chosen, record = _judged(context, plans, reach, record, pool, deadline)
    timings["judge"] = time.perf_counter() - tic
    if chosen == PUSH:
        return _unchanged(candidate, record, deadline, timings)
    goal = found.goals[int(chosen.removeprefix("room"))]
    q = plans[chosen]
    record = replace(record, moves=tuple(m.to_data() for m in goal.moves),
                     budget=deadline.record())
    trajectory = Trajectory(np.arange(len(q)) * config.baseline.knot_time, q)
    return Candidate(candidate.alpha, CandidateStatus.OK, "", trajectory, "rearrange",
                     dict(candidate.timings) | timings, record.to_details())


def sequence_path(goal: State, reach: np.ndarray) -> np.ndarray:
    """The knots (K, 8) of a goal's pushes, the gripper opened at q0 over `OPENING_KNOTS`,
    then the reach (T + 1, 8); every push starts and ends at the reach's first knot."""
    opening = reach[0].copy()
    ramp = [opening.copy() for _ in range(OPENING_KNOTS)]
    for k, row in enumerate(ramp):
        row[ARM] = goal.paths[-1][-1, ARM] + (k + 1) / OPENING_KNOTS * (
            reach[0, ARM] - goal.paths[-1][-1, ARM])
    return np.vstack([*(p[:-1] for p in goal.paths), np.array(ramp), reach[1:]])


def held_to(paths: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Every path (K_i, 8) held at its first knot until all have the longest's knots."""
    n = max(len(q) for q in paths.values())
    return {k: np.vstack([np.repeat(q[:1], n - len(q), axis=0), q]) for k, q in paths.items()}


def _judged(context: PlanningContext, plans: dict[str, np.ndarray], reach: np.ndarray,
            record: RearrangeRecord, pool, deadline: Deadline) -> tuple[str, RearrangeRecord]:
    """The name of the plan returned (a sequence, or `PUSH`) and the record with the verdicts
    and the veto (module docstring)."""
    config, geometry = context.config, context.arm()
    paths = held_to(plans | {PUSH: reach})
    times = np.arange(len(paths[PUSH])) * config.baseline.knot_time
    verdicts = judge_paths(context.scene, paths, times, config, geometry, pool,
                           complete=False, deadline=deadline.at)
    summaries = {n: _summary(v) for n, v in verdicts.items()}
    rooms = [n for n in plans if n in verdicts]
    why = "budget" if PUSH not in verdicts or not rooms else ""
    best = min(rooms, key=lambda n: verdicts[n].key()) if rooms else None
    if not why and (verdicts[best].p_success < config.rearrange.acceptance
                    or not _beats(verdicts[best], verdicts[PUSH], config, True)):
        why = "not accepted"
    veto: dict = {}
    if not why:
        cfg = config.phi_judge
        held_out = list(range(cfg.members, cfg.members + cfg.veto_members))
        again = judge_paths(context.scene, {n: paths[n] for n in (best, PUSH)}, times, config,
                            geometry, pool, members=held_out, complete=False,
                            deadline=deadline.at)
        wins = len(again) == 2 and _beats(again[best], again[PUSH], config, False)
        veto = {"members": held_out, "wins": wins, "cut": len(again) < 2,
                **{n: _summary(v) for n, v in again.items()}}
        why = "" if wins else ("budget" if len(again) < 2 else "veto")
    chosen = best if not why else PUSH
    return chosen, replace(record, chosen=chosen, why=why, verdicts=summaries, veto=veto)


def _beats(room: PhiVerdict, push: PhiVerdict, config: Config, margin: bool) -> bool:
    """Whether a sequence's verdict beats the push answer's: by `PhiVerdict.key` (``margin``)
    or `class_key`; with ``rearrange.prefer_room`` a tie of the classes goes to the sequence
    (geometry says the push answer's reach is crowded)."""
    if config.rearrange.prefer_room and room.class_key()[:2] == push.class_key()[:2]:
        return True
    return (room.key() < push.key()) if margin else (room.class_key() < push.class_key())


def _summary(verdict: PhiVerdict) -> dict:
    """A judged plan's line in the record."""
    return {"p_success": verdict.p_success, "expected_grade": verdict.expected_grade,
            "kinds": [r.kind for r in verdict.readings]}


def _unchanged(candidate: Candidate, record: RearrangeRecord, deadline: Deadline,
               timings: dict | None = None) -> Candidate:
    """The push candidate returned as it is, relabelled "rearrange", with ``record``."""
    record = replace(record, chosen=PUSH, moves=(), budget=deadline.record())
    return Candidate(candidate.alpha, candidate.status, candidate.reason, candidate.trajectory,
                     "rearrange", dict(candidate.timings) | (timings or {}),
                     record.to_details())


def rearrange_table(candidates: list[Candidate]) -> str:
    """A text table, one row per angle: the plan returned, the boxes crowding the reach, the
    pushes, P(success) in phi of the plan and of the push answer, the seconds."""
    rows = [f"{'alpha':>7} {'plan':>34} {'crowd':>5} {'P phi':>6} {'push':>6} {'s':>6}"]
    for c in candidates:
        record = RearrangeRecord.from_details(c.details or {})
        mine = (record.verdicts.get(record.chosen) or {}).get("p_success", float("nan"))
        push = (record.verdicts.get(PUSH) or {}).get("p_success", float("nan"))
        rows.append(f"{c.alpha:7.3f} {record.label[:34]:>34} {len(record.crowd):5d} "
                    f"{mine:6.2f} {push:6.2f} {sum(c.timings.values()):6.1f}")
    return "\n".join(rows)
