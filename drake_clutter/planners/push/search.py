"""The push planner's search (beyond the paper): predictive sampling over the push family,
scored by the judge in phi, with a veto on members it never saw.

Given straight start paths of one approach angle (the baseline's at several grasp heights and
yaws, knots at the same times, the first the baseline's own), in rounds (``push_search``):

1. **Round 1**: ``samples`` family members (`aim.draw`: aimed at the boxes each start's path
   meets) are drawn around the starts in turn, each built (`family.member_path`) and kept if
   feasible: every knot on its target within 1 mm, the judge's joint and speed limits
   (`trajectory.plan_limit_violation`), the baseline's dense shelf check. The starts and the
   kept members are judged together in phi (`phi_judge.judge_paths`: members 0 .. K - 1, K =
   ``phi_judge.members``, phi's engine ``phi_judge.engine``).
2. **Later rounds** (``method``): the ``elite`` best bent paths so far are the means of the
   round's sampling distribution, and copies of them with their via-points jittered
   (`perturb`) are built, checked and judged in the same members (their verdicts compare with
   the earlier ones: same worlds, same seeds).

   - "perturb": each elite path gets ``perturbations`` copies, the jitter's spreads fixed at
     ``jitter_progress`` and ``jitter_offset``.
   - "cem" (cross-entropy, as MuJoCo MPC's planner runs it over its parameters): ``population``
     copies, over the elite in turn; the spreads start at the jitter's and after each round
     are refit to the elite (`Search.refit`): the root mean square of each elite path's
     offsets from the path it was drawn from, per kind (times and progresses; sideways and
     vertical offsets), mixed with the old spread by ``smoothing`` and floored at
     ``spread_floor_progress`` and ``spread_floor_offset``. An elite of first-round draws
     alone leaves the spreads as they are.
3. **The pick**: the best verdict (`PhiVerdict.key`: P(success), expected grade, the margin
   (how near the classes' limits), boxes disturbed; ties to the earlier path, starts first).
   The elite of a later round is ranked the same way, so paths that all fail are perturbed
   from those that came nearest.
4. **The veto**: a bent pick replaces the best start only if its classes' reading on
   ``veto_members`` members the search never saw (indices K .. K + veto - 1;
   `PhiVerdict.class_key`, the margin left out) is strictly better than the best start's
   there. Otherwise the best start is returned; that is also the answer when every start
   reads P(success) >= ``stop_at`` already (no member drawn) or no member is feasible.
5. **The time budget** (the push planner's `budget.Deadline`, ``push_search.time_budget``
   for the whole initialization): no round starts and no knot is stepped once it has passed
   (``record["stopped"]`` says when); a path not rolled out in every member by then has no
   verdict and is left out (``counts["unjudged"]``). The pick is made on what was judged; a
   veto the budget cuts keeps the best start; when no start was judged the first (the
   baseline's own) is returned.

The search never fails the plan: a member that cannot be built is dropped and counted, and a
rollout phi cannot finish reads as a kinematic failure (`judge_paths`). Every draw is seeded
with ``[push_search.seed, angle index, round]``. Bullet and the mesh arm are not used.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from drake_clutter.common.config import PushSearchConfig
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import PhiVerdict, judge_paths
from drake_clutter.planners.push.aim import draw, obstructions
from drake_clutter.planners.push.family import PushPath, ViaPoint, feasible, member_path
from drake_clutter.planners.tool_path import approach_frame


@dataclass(frozen=True)
class Sample:
    """A path the search judged: its start's name, its member (None: the start itself) and
    its knots (T + 1, 8)."""

    start: str
    member: PushPath | None
    q: np.ndarray
    parent: str | None = None  # the judged path it was drawn from (None: a start or a draw)


@dataclass(frozen=True)
class SearchResult:
    """The path returned (T + 1, 8), its name (a start's or "<start>/r<round>m<i>") and the
    record (JSON-ready: every judged path's verdict summary, the counts, the veto, seconds)."""

    name: str
    q: np.ndarray
    record: dict


def perturb(rng: np.random.Generator, member: PushPath, search: PushSearchConfig,
            spread: tuple[float, float] | None = None) -> PushPath:
    """``member`` with each via-point's time and progress (and the gripper's opening time,
    if it has one) moved by N(0, progress spread) and its offsets by N(0, offset spread) (m);
    times and progresses kept in [0.02, 0.98] and the times in order. ``spread``: (progress
    fraction, offset m); None: ``jitter_progress`` and ``jitter_offset``."""
    sd_progress, sd_offset = spread or (search.jitter_progress, search.jitter_offset)
    vias = []
    for v in member.vias:
        knot, progress = np.clip(np.array([v.knot, v.progress])
                                 + rng.normal(0.0, sd_progress, 2), 0.02, 0.98)
        lateral, vertical = np.array([v.lateral, v.vertical]) + rng.normal(
            0.0, sd_offset, 2)
        vias.append(ViaPoint(float(knot), float(progress), float(lateral), float(vertical)))
    knots = sorted(v.knot for v in vias)
    vias = [replace(v, knot=k) for v, k in zip(vias, knots, strict=True)]
    open_at = (float(np.clip(member.open_at + rng.normal(0.0, sd_progress), 0.02,
                             0.98)) if member.open_at else 0.0)
    return PushPath(tuple(vias), open_at)


def offsets(child: PushPath, parent: PushPath) -> tuple[np.ndarray, np.ndarray]:
    """How far ``child`` lies from the ``parent`` it was perturbed from: the differences of
    the via-points' times and progresses (and of the opening time, if any; fractions) and of
    their sideways and vertical offsets (m)."""
    a = np.array([[v.knot, v.progress, v.lateral, v.vertical] for v in child.vias])
    b = np.array([[v.knot, v.progress, v.lateral, v.vertical] for v in parent.vias])
    progress = np.r_[(a[:, :2] - b[:, :2]).ravel(),
                     [child.open_at - parent.open_at] if parent.open_at else []]
    return progress, (a[:, 2:] - b[:, 2:]).ravel()


class Search:
    """One approach angle's search (module docstring): the starts, the worlds to check and
    judge them in, and every path judged so far."""

    def __init__(self, context: PlanningContext, starts: dict[str, np.ndarray],
                 times: np.ndarray, pool=None, deadline: Deadline | None = None):
        config = context.config
        self.scene, self.times, self.config = context.scene, np.asarray(times, float), config
        self.pool = pool
        self.deadline = deadline or Deadline(None)
        self.geometry, self.clearance = context.arm(), context.clearance
        search = config.push_search
        self.samples = {name: Sample(name, None, np.asarray(q, float))
                        for name, q in starts.items()}
        self.verdicts: dict[str, PhiVerdict] = {}
        self.counts = {"drawn": 0, "feasible": 0, "unjudged": 0}
        self.spread = (search.jitter_progress, search.jitter_offset)  # (fraction, m)
        self._frames = {}

    def add(self, name: str, start: str, member: PushPath, parent: str | None = None) -> bool:
        """Builds ``member`` about the start path ``start`` (drawn from the judged path
        ``parent``, if any) and keeps it as ``name`` if feasible; nothing is built once the
        deadline has passed."""
        if self.deadline.spend("draws"):
            return False
        self.counts["drawn"] += 1
        try:
            q, error = member_path(self.geometry, self.samples[start].q, member)
        except (RuntimeError, ValueError):
            return False
        if not feasible(q, error, self.times, self.clearance, self.config):
            return False
        self.counts["feasible"] += 1
        self.samples[name] = Sample(start, member, q, parent)
        return True

    def judge(self, names: list[str], members=None) -> dict[str, PhiVerdict]:
        """The verdicts of the named paths in the search's members (or ``members``); a path
        the deadline cut has none (counted as unjudged)."""
        if not names:
            return {}
        found = judge_paths(self.scene, {n: self.samples[n].q for n in names}, self.times,
                            self.config, self.geometry, self.pool, members,
                            complete=False, deadline=self.deadline.at)
        self.counts["unjudged"] += len(names) - len(found)
        if len(found) < len(names):
            self.deadline.spend("judging")
        return found

    def frame(self, start: str):
        """The approach frame and the met boxes of a start path (computed once)."""
        if start not in self._frames:
            q = self.samples[start].q
            frame = approach_frame(self.geometry, q)
            self._frames[start] = (frame, obstructions(self.geometry, q, frame,
                                                       self.scene.target))
        return self._frames[start]

    def ranked(self, names) -> list[str]:
        """The judged paths ``names``, best first (ties to the earlier): by `PhiVerdict.key`,
        or by its classes' reading alone (`PhiVerdict.class_key`) without
        ``push_search.margin``."""
        order = {n: i for i, n in enumerate(self.samples)}
        margin = self.config.push_search.margin
        return sorted(names, key=lambda n: (*(self.verdicts[n].key() if margin
                                              else self.verdicts[n].class_key()), order[n]))

    def best(self, names) -> str:
        """The best judged path among ``names`` (ties to the earlier)."""
        return self.ranked(names)[0]

    def elite(self) -> list[str]:
        """The ``push_search.elite`` best bent paths judged so far, best first."""
        bent = [n for n in self.verdicts if self.samples[n].member is not None]
        return self.ranked(bent)[:self.config.push_search.elite]

    def refit(self) -> tuple[float, float]:
        """The cross-entropy update of the spreads (module docstring) from the elite; returns
        and keeps the new (progress fraction, offset m)."""
        cfg = self.config.push_search
        drawn = [self.samples[n] for n in self.elite() if self.samples[n].parent is not None]
        if not drawn:
            return self.spread
        steps = [offsets(d.member, self.samples[d.parent].member) for d in drawn]
        fitted = [float(np.sqrt(np.mean(np.concatenate([st[k] for st in steps]) ** 2)))
                  for k in (0, 1)]
        floors = (cfg.spread_floor_progress, cfg.spread_floor_offset)
        self.spread = tuple(max(floor, cfg.smoothing * old + (1.0 - cfg.smoothing) * new)
                            for old, new, floor in zip(self.spread, fitted, floors,
                                                       strict=True))
        return self.spread

    def veto(self, pick: str, best_start: str) -> tuple[str, dict | None]:
        """The path returned: ``pick`` if it is a start, or if its classes' reading also beats
        ``best_start``'s on the held-out members; else ``best_start`` (also when the budget
        cuts the veto). The veto's verdicts (None: no veto run)."""
        if self.samples[pick].member is None:
            return pick, None
        cfg = self.config.phi_judge
        held_out = range(cfg.members, cfg.members + cfg.veto_members)
        verdicts = {} if self.deadline.spend("veto") else self.judge([pick, best_start],
                                                                      held_out)
        if len(verdicts) < 2:  # the budget ran out before or during the veto: start kept
            return best_start, {"members": list(held_out), "wins": False, "cut": True}
        wins = verdicts[pick].class_key() < verdicts[best_start].class_key()
        return (pick if wins else best_start), {
            "members": list(held_out), "wins": wins,
            **{n: {"p_success": v.p_success, "expected_grade": v.expected_grade}
               for n, v in verdicts.items()}}


def run_search(context: PlanningContext, starts: dict[str, np.ndarray], times: np.ndarray,
               index: int = 0, pool=None, deadline: Deadline | None = None, observe=None
               ) -> SearchResult:
    """The search of one approach angle (``index``, seeds the draws) in the scene's planning
    ``context`` (its worlds; its configuration the settings) from the straight ``starts``
    (name: knots (T + 1, 8), the first the baseline's; knots at ``times`` s); see the module
    docstring. ``pool``: a `phi.workers.WorkerPool` the members are rolled out in (the same
    result); ``deadline``: the initialization's budget (None: none); ``observe``: called as
    ``observe(round, search, best_start)`` after each round (to read the search at any time;
    it must not change it)."""
    tic = time.perf_counter()
    cfg = context.config.push_search
    s = Search(context, starts, times, pool, deadline)
    s.verdicts.update(s.judge(list(starts)))
    judged = [n for n in starts if n in s.verdicts]
    if not judged:
        return _unjudged(s, list(starts), tic)
    best_start = s.best(judged)
    record = {"starts": list(starts), "best_start": best_start, "rounds": []}
    if len(judged) < len(starts):
        record["stopped"] = "time_budget while judging the starts"
    elif s.verdicts[best_start].p_success < cfg.stop_at:
        for round_ in range(cfg.rounds):
            if s.deadline.spend(f"search round {round_ + 1}"):
                record["stopped"] = f"time_budget after {round_} rounds"
                break
            rng = np.random.default_rng([cfg.seed, index, round_])
            names = (_draw_round(s, rng, list(starts)) if round_ == 0
                     else LATER_ROUNDS[cfg.method](s, rng, round_))
            s.verdicts.update(s.judge(names))
            spread = s.refit() if cfg.method == "cem" else s.spread
            record["rounds"].append({"judged": len(names), "best": s.best(list(s.verdicts)),
                                     "spread": list(spread)})
            if observe is not None:
                observe(round_, s, best_start)
    pick = s.best(list(s.verdicts))
    chosen, veto = s.veto(pick, best_start)
    record.update(counts=s.counts, pick=pick, veto=veto, chosen=chosen,
                  seconds=time.perf_counter() - tic,
                  verdicts={n: _summary(v, s.samples[n]) for n, v in s.verdicts.items()})
    return SearchResult(chosen, s.samples[chosen].q, record)


def _unjudged(s: Search, starts: list[str], tic: float) -> SearchResult:
    """The first start (the baseline's own path), unjudged: the budget ran out first."""
    record = {"starts": starts, "best_start": None, "rounds": [], "counts": s.counts,
              "stopped": "time_budget before a start was judged", "pick": None, "veto": None,
              "chosen": starts[0], "seconds": time.perf_counter() - tic, "verdicts": {}}
    return SearchResult(starts[0], s.samples[starts[0]].q, record)


def _draw_round(s: Search, rng: np.random.Generator, starts: list[str]) -> list[str]:
    """Round 1: ``samples`` members drawn around the starts in turn; the kept names."""
    kept = []
    for i in range(s.config.push_search.samples):
        start = starts[i % len(starts)]
        frame, found = s.frame(start)
        name = f"{start}/r0m{i}"
        if s.add(name, start, draw(rng, frame, found, s.config.push_search)):
            kept.append(name)
    return kept


def _perturb_round(s: Search, rng: np.random.Generator, round_: int) -> list[str]:
    """A later round ("perturb"): the elite bent paths each perturbed ``perturbations``
    times at the fixed spreads; the kept names."""
    cfg = s.config.push_search
    kept = []
    for e, name in enumerate(s.elite()):
        sample = s.samples[name]
        for j in range(cfg.perturbations):
            new = f"{sample.start}/r{round_}m{e * cfg.perturbations + j}"
            if s.add(new, sample.start, perturb(rng, sample.member, cfg), parent=name):
                kept.append(new)
    return kept


def _cem_round(s: Search, rng: np.random.Generator, round_: int) -> list[str]:
    """A later round ("cem"): ``population`` paths drawn about the elite in turn at the
    search's current spreads; the kept names."""
    cfg = s.config.push_search
    elite = s.elite()
    kept = []
    for i in range(cfg.population if elite else 0):
        name = elite[i % len(elite)]
        sample = s.samples[name]
        new = f"{sample.start}/r{round_}m{i}"
        if s.add(new, sample.start, perturb(rng, sample.member, cfg, s.spread), parent=name):
            kept.append(new)
    return kept


LATER_ROUNDS = {"perturb": _perturb_round, "cem": _cem_round}  # push_search.method


def _summary(verdict: PhiVerdict, sample: Sample) -> dict:
    """A judged path's line in the record."""
    margin = verdict.margin
    return {"p_success": verdict.p_success, "expected_grade": verdict.expected_grade,
            "margin": margin if np.isfinite(margin) else None,
            "kinds": [r.kind for r in verdict.readings],
            "member": None if sample.member is None else sample.member.to_data()}
