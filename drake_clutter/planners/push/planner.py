"""The push planner (beyond the paper): per approach angle, the baseline's straight path at
each grasp height and yaw of ``starts.grasp_heights`` and ``starts.approach_offsets``
(`starts.height_candidates`); the first of them that keeps off the boxes
(`geometry.clear_paths`, with ``push_search.clear_first``), else the sampling search over the push
family from them all, scored by the judge in phi (`search.run_search`).

The scene's planning worlds are built once (`context.PlanningContext`) and serve every angle.
Where the baseline's own path failed (IK, the optimiser, the dense shelf check), the other
heights are planned all the same, and where none plans, the line turned toward the shelf's
axis (`starts.planned_starts`, ``starts.recovery_turns``); a path planned so records the
baseline's failure in ``details["recovered"]`` and never falls back to it. With no start at
all the baseline's failure comes back as it is, relabelled "push". A search that finds
nothing better returns its best start, recorded as such. With ``push_search.fallback``, a
search whose pick reads neither success nor partial success in any member of phi returns the
baseline's own path instead (``details["chosen"]`` "baseline", the search's pick kept in
``details["search"]["chosen"]``): among paths that all fail in phi, its reading of which failure
is least bad is weakest on falls.

``push_search.time_budget`` (s) bounds the whole initialization: the starts stop being planned,
draws built and knots stepped once it has passed (`budget.Deadline`), and the best path judged
so far is returned; with none judged, the baseline's own path ("baseline"). What it cut is in
``details["budget"]``.
"""

from __future__ import annotations

import math
import time

from drake_clutter.common.config import Config
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import clear_paths
from drake_clutter.planners.loop import refine_each
from drake_clutter.planners.push.record import FALLBACK, PushRecord
from drake_clutter.planners.push.search import run_search
from drake_clutter.planners.starts import planned_starts, start_key
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory


def plan_push(scene: Scene, config: Config, start: list[Candidate]) -> list[Candidate]:
    """One "push" Candidate per baseline candidate in ``start``, in order (module
    docstring; `loop.refine_each`: phi's members are rolled out in ``dynamics.workers``
    worker processes, 0: in this one)."""
    return refine_each(scene, config, start, push_candidate)


def push_candidate(context: PlanningContext, candidate: Candidate, index: int,
                   pool=None, started: float | None = None) -> Candidate:
    """The push planner on one baseline candidate (angle ``index`` of the baseline's) in the
    scene's planning ``context``; ``pool``: `run_search`'s; ``started``: the `time.monotonic`
    value its budget counts from (None: now)."""
    scene, config, geometry = context.scene, context.config, context.arm()
    deadline = Deadline(config.push_search.time_budget, start=started or time.monotonic())
    tic = time.perf_counter()
    found = planned_starts(context, candidate, deadline)
    timings = {"heights": time.perf_counter() - tic}
    if not found:
        return failed(candidate, timings, deadline)
    starts = {start_key(*key): c.trajectory.q for key, c in found.items()}
    times = next(iter(found.values())).trajectory.times
    clear = clear_paths(geometry, starts, config, scene.target) if (
        config.push_search.clear_first) else []
    recovered = {} if candidate.ok else {"status": candidate.status.value,
                                         "reason": candidate.reason}
    if clear:
        record = PushRecord(clear[0], tuple(clear), recovered=recovered,
                            budget=deadline.record(), initialization=candidate.planner)
        trajectory = Trajectory(times.copy(), starts[clear[0]])
        return Candidate(candidate.alpha, CandidateStatus.OK, "", trajectory, planner="push",
                         timings=timings, details=record.to_details())
    tic = time.perf_counter()
    result = run_search(context, starts, times, index, pool, deadline)
    timings["search"] = time.perf_counter() - tic
    chosen, trajectory = result.name, Trajectory(times.copy(), result.q)
    if candidate.ok and falls_back(result.record["verdicts"].get(result.name), config):
        chosen = FALLBACK
        trajectory = Trajectory(candidate.trajectory.times.copy(),
                                candidate.trajectory.q.copy())
    record = PushRecord(chosen, search=result.record, recovered=recovered,
                        budget=deadline.record(), initialization=candidate.planner)
    return Candidate(candidate.alpha, CandidateStatus.OK, "", trajectory, planner="push",
                     timings=timings, details=record.to_details())


def failed(candidate: Candidate, timings: dict, deadline: Deadline) -> Candidate:
    """The baseline's failed ``candidate``, relabelled "push", when no start planned at its
    angle, turned or not: its status and reason, the starts' ``timings`` (s) added."""
    details = PushRecord.failed(candidate.details, deadline.record()).to_details()
    return Candidate(candidate.alpha, candidate.status, candidate.reason, candidate.trajectory,
                     "push", dict(candidate.timings) | timings, details)


def falls_back(verdict: dict | None, config: Config) -> bool:
    """Whether the baseline's own path replaces the search's chosen path, whose verdict
    summary is ``verdict`` (None: not judged): with ``push_search.fallback``, when it reads
    no grasp in any member of phi."""
    return verdict is None or (config.push_search.fallback and not reads_a_grasp(verdict))


def reads_a_grasp(verdict: dict) -> bool:
    """Whether a judged path's verdict summary (`search.run_search`'s record) reads success or
    partial success in any member of phi."""
    return any(kind in ("success", "partial_success") for kind in verdict["kinds"])


def push_table(candidates: list[Candidate]) -> str:
    """A text table, one row per angle: the path chosen, its and the best start's P(success)
    in phi, the members drawn and kept, and the seconds."""
    rows = [f"{'alpha':>7} {'chosen':>22} {'P phi':>6} {'start':>6} {'kept':>9} {'s':>6}"]
    for c in candidates:
        record = PushRecord.from_details(c.details or {})
        search = record.search
        if c.ok and record.clear:
            rows.append(f"{c.alpha:7.3f} {record.chosen + ' (clear)':>22} {'':>6} {'':>6} "
                        f"{'':>9} {sum(c.timings.values()):6.1f}")
            continue
        if not c.ok or not search:
            rows.append(f"{c.alpha:7.3f} {c.status.value:>22}")
            continue
        verdicts = search["verdicts"]
        counts = search["counts"]
        chosen, start = (verdicts.get(search[k]) or {"p_success": math.nan}
                         for k in ("chosen", "best_start"))
        rows.append(f"{c.alpha:7.3f} {record.chosen:>22} "
                    f"{chosen['p_success']:6.2f} {start['p_success']:6.2f} "
                    f"{counts['feasible']:>4}/{counts['drawn']:<4} "
                    f"{sum(c.timings.values()):6.1f}")
    return "\n".join(rows)
