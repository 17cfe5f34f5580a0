"""A sampling search around a candidate path (beyond the paper), scored by phi's ensemble.

Which side of a box to pass, whether to push it, whether a cascade starts: those choices are
nearly combinatorial, and phi's gradients through them are chaotic. The search (cross-entropy
method, Rubinstein 1999; as in sampling MPC) looks over a four-number family of paths around a
start path q (T + 1, 8):

* ``lateral`` and ``height`` (m): the tool frame G moved along W's y and z;
* ``yaw`` (rad): G turned about W's z (the approach direction swung sideways);
* ``opening`` (m): added to the gripper's opening;

each scaled at knot t by a bump, sin^2 over the knots from ``begin`` to the last, zero with
zero slope at both, so the knots up to ``begin`` and the pre-grasp pose are kept exactly.
``begin`` is ``physics.search_lead_knots`` before the start path's first arm-box contact in
phi: the arm touches nothing before it, and every sample shares those knots. The joint
offsets at a knot are G's twist mapped through the damped least-squares inverse of its
Jacobian there (first order: the offsets are a few cm). A sample is kept only if it stays
within the joint limits, moves no joint per knot faster than the start path or ``max_steps``
allows, and passes the baseline's dense shelf check; every kept sample is scored by the
ensemble (`ensemble.score_in_members`; all samples meet the same members), and the best path
found is returned, the start included: the search never returns a path worse than its start
in ensemble score.

Cost: with ``physics.search_shared_phi`` each member's phi is built, pruned and settled once
for the whole search, pruned for the starts with ``search_prune_margin`` more margin so the
samples' own sweeps stay inside it; the shared knots' phi steps are then taken once (phi's
step cache). A round whose samples reach boxes that phi holds frozen rebuilds the members,
pruned for those samples too, and is scored again (``search_rebuilds`` times at most; the best
path so far is priced again in the new members); a sample that still reaches one is not
scored (its score would miss that box) and is counted. Without ``search_shared_phi`` each
round's samples get their own exactly pruned phis (`ensemble.ensemble_scores`), as a
reference.
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.clearance import ShelfClearance, dense_check
from drake_clutter.planners.physics.ensemble import (
    ensemble_scores,
    first_contact_knot,
    member_problems,
    score_in_members,
)
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.scene.scenes import Scene

ARM = 7  # arm joints; column 7 of a path is the gripper opening (m)
DAMPING = 1e-4  # damped least squares: lambda^2 added to J J^T (m^2, rad^2)


@dataclass(frozen=True)
class PathOffset:
    """One sample's parameters: G moved along W's y and z (m), turned about W's z (rad), the
    gripper's opening widened (m), each at its full size at the path's middle knot."""

    lateral: float = 0.0
    height: float = 0.0
    yaw: float = 0.0
    opening: float = 0.0

    def vector(self) -> np.ndarray:
        """(lateral, height, yaw, opening)."""
        return np.array([self.lateral, self.height, self.yaw, self.opening])


def bump(num_knots: int, begin: int = 0) -> np.ndarray:
    """sin^2(pi (t - begin) / (T - begin)) at the knots t = begin..T (T = num_knots - 1), 0
    before: 0 with zero slope at ``begin`` and at T, 1 halfway between."""
    t = np.arange(num_knots, dtype=float)
    s = np.clip((t - begin) / max(num_knots - 1 - begin, 1), 0.0, 1.0)
    return np.sin(np.pi * s) ** 2


def offset_path(geometry: ArmGeometry, q: np.ndarray, offset: PathOffset,
                lo: np.ndarray, hi: np.ndarray, begin: int = 0) -> np.ndarray:
    """The path q (T + 1, 8) with ``offset`` applied knot by knot from ``begin`` on (module
    docstring), clipped into the per-control bounds lo, hi (8,)."""
    out = np.array(q, dtype=float)
    b = bump(len(q), begin)
    twist = np.array([0.0, 0.0, offset.yaw, 0.0, offset.lateral, offset.height])  # [w; v] in W
    for t in range(1, len(q) - 1):
        if b[t] == 0.0:
            continue
        _, J = geometry.tool_jacobian(q[t])
        Ja = J[:, :ARM]
        dq = Ja.T @ np.linalg.solve(Ja @ Ja.T + DAMPING * np.eye(6), b[t] * twist)
        out[t, :ARM] += dq
        out[t, ARM] += b[t] * offset.opening
    return np.clip(out, lo, hi)


def speed_ok(q: np.ndarray, start: np.ndarray, steps: np.ndarray) -> bool:
    """No coordinate moves per knot interval more than ``steps`` (8,) or the start path's own
    move there, whichever is larger."""
    allowed = np.maximum(np.abs(np.diff(start, axis=0)), steps[None, :]) + 1e-9
    return bool(np.all(np.abs(np.diff(q, axis=0)) <= allowed))


@dataclass
class SearchResult:
    """The best path found (the start when nothing beat it), its score and the start's, the
    first knot the offsets move (``begin``), the start the search centred on, and per round:
    samples drawn, kept (feasible), not scored because they reached a frozen box, whether the
    round rebuilt the members, the round's best score."""

    q: np.ndarray
    score: float
    start_score: float
    rounds: list[dict]
    best: PathOffset
    begin: int = 0
    centre: np.ndarray | None = None


class _Scorer:
    """Ensemble scores of named paths (T + 1, 8) in members built once for the search
    (``shared``: pruned for the starts with the extra margin, rebuilt to take in the boxes a
    round's samples reached), or in members built for each call's paths. Close it after use."""

    def __init__(self, scene: Scene, starts: dict[str, np.ndarray], config: Config, pool,
                 knot_time: float | None):
        self.scene, self.config, self.pool, self.knot_time = scene, config, pool, knot_time
        self.shared = config.physics.search_shared_phi
        self.prune_for, self.problems, self.rebuilds = dict(starts), None, 0
        self._stack = ExitStack()
        if self.shared:
            self._open()

    def _open(self) -> None:
        self._stack.close()
        self._stack = ExitStack()
        self.problems = self._stack.enter_context(member_problems(
            self.scene, self.prune_for, self.config, self.pool, self.knot_time,
            extra_margin=self.config.physics.search_prune_margin))

    def close(self) -> None:
        """Closes the shared members' phis."""
        self._stack.close()

    def __call__(self, paths: dict[str, np.ndarray]) -> tuple[dict[str, float], int]:
        """Each path's score (inf where it reached a frozen box) and how many did; with shared
        members, a round whose paths reached frozen boxes rebuilds them pruned for those paths
        too (at most ``search_rebuilds`` times) and is scored again."""
        if not self.shared:
            scores, _ = ensemble_scores(self.scene, paths, self.config, self.pool,
                                        self.knot_time)
            return scores, 0
        scores, _, frozen = score_in_members(self.problems, paths, self.config)
        reached = [n for n in paths if frozen[n]]
        if reached and self.rebuilds < self.config.physics.search_rebuilds:
            self.rebuilds += 1
            self.prune_for.update({f"reached{len(self.prune_for)}": paths[n] for n in reached})
            self._open()
            scores, _, frozen = score_in_members(self.problems, paths, self.config)
        return {n: (np.inf if frozen[n] else v) for n, v in scores.items()}, sum(frozen.values())

    def begin(self, q: np.ndarray, lead: int) -> int:
        """The knot the offsets start from: ``lead`` knots before q's first arm-box contact in
        the nominal member (0 without shared members or contact)."""
        if self.problems is None:
            return 0
        t = first_contact_knot(self.problems[0], q)
        return 0 if t is None else max(0, t + 1 - lead)


def sampling_search(scene: Scene, q: np.ndarray, config: Config, lo: np.ndarray,
                    hi: np.ndarray, steps: np.ndarray, pool=None,
                    knot_time: float | None = None,
                    alternatives: tuple[np.ndarray, ...] = ()) -> SearchResult:
    """The cross-entropy search around the path q (T + 1, 8) (module docstring) - or around
    the one of ``alternatives`` (same start knot) with a lower ensemble score: ``physics.
    search_rounds`` rounds of ``search_samples`` draws from a Gaussian over (lateral, height,
    yaw, opening), started at zero with the ``search_*`` half-ranges as its standard
    deviations and truncated to them, refitted to the best ``search_elite`` fraction; seeded
    with ``search_seed``. The best sample and the centre are scored again in the search's
    last members: ``score`` and ``start_score`` are those two scores, and the centre is
    returned unless the sample's is lower."""
    starts = {f"start{i}": np.array(p, dtype=float) for i, p in enumerate((q, *alternatives))}
    score = _Scorer(scene, starts, config, pool, knot_time)
    try:
        return _search_rounds(scene, starts, config, lo, hi, steps, score)
    finally:
        score.close()


def _search_rounds(scene: Scene, starts: dict[str, np.ndarray], config: Config,
                   lo: np.ndarray, hi: np.ndarray, steps: np.ndarray,
                   score: _Scorer) -> SearchResult:
    cfg = config.physics
    rng = np.random.default_rng(cfg.search_seed)
    ranges = np.array([cfg.search_lateral, cfg.search_height, cfg.search_yaw,
                       cfg.search_opening])
    mean, std = np.zeros(4), ranges.copy()
    geometry = ArmGeometry(scene, "capsules")
    clearance = ShelfClearance(static_planning_world(scene))
    scores, _ = score(starts)
    centre = min(starts, key=lambda n: (scores[n], n))
    start = starts[centre]
    begin = score.begin(start, cfg.search_lead_knots)
    best_q, best_score, best, rounds = start, scores[centre], PathOffset(), []
    for _ in range(cfg.search_rounds):
        draws = np.clip(mean + std * rng.standard_normal((cfg.search_samples, 4)),
                        -ranges, ranges)
        paths, offsets = {}, {}
        for i, v in enumerate(draws):
            offset = PathOffset(*map(float, v))
            path = offset_path(geometry, start, offset, lo, hi, begin)
            if (speed_ok(path, start, steps)
                    and dense_check(clearance, path[:, :ARM], config.baseline).passed):
                paths[f"s{i}"], offsets[f"s{i}"] = path, offset
        record = {"drawn": len(draws), "kept": len(paths), "reached_frozen": 0, "best": None}
        rounds.append(record)
        if not paths:
            continue
        rebuilds = score.rebuilds
        round_scores, record["reached_frozen"] = score(paths)
        record["rebuilt"] = score.rebuilds != rebuilds
        if record["rebuilt"]:  # new phis: the best so far is priced in them again
            best_score = score({"best": best_q})[0]["best"]
        ranked = sorted(paths, key=lambda n: round_scores[n])
        if np.isfinite(round_scores[ranked[0]]):
            record["best"] = round_scores[ranked[0]]
        if round_scores[ranked[0]] < best_score:
            best_q, best_score, best = paths[ranked[0]], round_scores[ranked[0]], offsets[ranked[0]]
        elite = [offsets[n].vector() for n in ranked[:max(1, int(cfg.search_elite * len(ranked)))]
                 if np.isfinite(round_scores[n])]
        if elite:
            mean = np.mean(elite, axis=0)
            std = np.maximum(np.std(elite, axis=0), 0.1 * ranges)
    # Shared members: both already rolled out there (step caches); else fresh members.
    final, _ = score({"centre": start, "best": best_q})
    if not final["best"] < final["centre"]:
        best_q, best = start, PathOffset()
    return SearchResult(best_q, min(final["best"], final["centre"]), final["centre"], rounds,
                        best, begin, start)

