"""A sampling search around a candidate path (beyond the paper), scored by phi's ensemble.

Which side of a box to pass, whether to push it, whether a cascade starts: those choices are
nearly combinatorial, and phi's gradients through them are chaotic. The search (cross-entropy
method, Rubinstein 1999; as in sampling MPC) looks over a four-number family of paths around a
start path q (T + 1, 8):

* ``lateral`` and ``height`` (m): the tool frame G moved along W's y and z;
* ``yaw`` (rad): G turned about W's z (the approach direction swung sideways);
* ``opening`` (m): added to the gripper's opening;

each scaled at knot t by the bump sin^2(pi t / T), zero with zero slope at the start and at
the last knot, so the start and the pre-grasp pose are kept exactly. The joint offsets at a
knot are G's twist mapped through the damped least-squares inverse of its Jacobian there
(first order: the offsets are a few cm). A sample is kept only if it stays within the joint
limits, moves no joint per knot faster than the start path or ``max_steps`` allows, and passes
the baseline's dense shelf check; every kept sample is scored by `ensemble.ensemble_scores`
(all samples of one round meet the same members), and the best path found is returned, the
start included: the search never returns a path worse than its start in ensemble score.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.clearance import ShelfClearance, dense_check
from drake_clutter.planners.physics.ensemble import ensemble_scores
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.robot import pr2
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


def bump(num_knots: int) -> np.ndarray:
    """sin^2(pi t / T) at the knots t = 0..T (T = num_knots - 1): 0 with zero slope at both
    ends, 1 at the middle."""
    t = np.arange(num_knots) / max(num_knots - 1, 1)
    return np.sin(np.pi * t) ** 2


def offset_path(geometry: ArmGeometry, q: np.ndarray, offset: PathOffset,
                lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The path q (T + 1, 8) with ``offset`` applied knot by knot (module docstring), clipped
    into the per-control bounds lo, hi (8,)."""
    out = np.array(q, dtype=float)
    b = bump(len(q))
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
    """The best path found (the start when nothing beat it), its score and the start's, and
    per round: samples drawn, kept (feasible), the round's best score."""

    q: np.ndarray
    score: float
    start_score: float
    rounds: list[dict]
    best: PathOffset


def sampling_search(scene: Scene, q: np.ndarray, config: Config, lo: np.ndarray,
                    hi: np.ndarray, steps: np.ndarray, pool=None,
                    knot_time: float | None = None,
                    alternatives: tuple[np.ndarray, ...] = ()) -> SearchResult:
    """The cross-entropy search around the path q (T + 1, 8) (module docstring) - or around
    the one of ``alternatives`` (same start knot) with a lower ensemble score: ``physics.
    search_rounds`` rounds of ``search_samples`` draws from a Gaussian over (lateral, height,
    yaw, opening), started at zero with the ``search_*`` half-ranges as its standard
    deviations and truncated to them, refitted to the best ``search_elite`` fraction; seeded
    with ``search_seed``. ``start_score`` is the centre's score."""
    cfg = config.physics
    rng = np.random.default_rng(cfg.search_seed)
    ranges = np.array([cfg.search_lateral, cfg.search_height, cfg.search_yaw,
                       cfg.search_opening])
    mean, std = np.zeros(4), ranges.copy()
    geometry = ArmGeometry(scene, "capsules")
    clearance = ShelfClearance(static_planning_world(scene))
    starts = {f"start{i}": np.array(p, dtype=float) for i, p in enumerate((q, *alternatives))}
    scores, _ = ensemble_scores(scene, starts, config, pool, knot_time)
    centre = min(starts, key=lambda n: (scores[n], n))
    start = starts[centre]
    best_q, best_score, best = start, scores[centre], PathOffset()
    start_score, rounds = best_score, []
    for _ in range(cfg.search_rounds):
        draws = np.clip(mean + std * rng.standard_normal((cfg.search_samples, 4)),
                        -ranges, ranges)
        paths, offsets = {}, {}
        for i, v in enumerate(draws):
            offset = PathOffset(*map(float, v))
            path = offset_path(geometry, start, offset, lo, hi)
            if (speed_ok(path, start, steps)
                    and dense_check(clearance, path[:, :ARM], config.baseline).passed):
                paths[f"s{i}"], offsets[f"s{i}"] = path, offset
        record = {"drawn": len(draws), "kept": len(paths), "best": None}
        rounds.append(record)
        if not paths:
            continue
        round_scores, _ = ensemble_scores(scene, paths, config, pool, knot_time)
        ranked = sorted(paths, key=lambda n: round_scores[n])
        record["best"] = round_scores[ranked[0]]
        if round_scores[ranked[0]] < best_score:
            best_q, best_score, best = paths[ranked[0]], round_scores[ranked[0]], offsets[ranked[0]]
        elite = [offsets[n].vector() for n in ranked[:max(1, int(cfg.search_elite * len(ranked)))]
                 if np.isfinite(round_scores[n])]
        if elite:
            mean = np.mean(elite, axis=0)
            std = np.maximum(np.std(elite, axis=0), 0.1 * ranges)
    return SearchResult(best_q, best_score, start_score, rounds, best)


def check_search(config: Config) -> list[tuple[str, bool, str]]:
    """(field, ok, what it must be) of the ``physics.search*`` fields."""
    cfg = config.physics
    return [("search_rounds", cfg.search_rounds >= 1, "at least 1"),
            ("search_samples", cfg.search_samples >= 1, "at least 1"),
            ("search_elite", 0 < cfg.search_elite <= 1, "in (0, 1]"),
            ("search_lateral", cfg.search_lateral >= 0, "non-negative"),
            ("search_height", cfg.search_height >= 0, "non-negative"),
            ("search_yaw", cfg.search_yaw >= 0, "non-negative"),
            ("search_opening", 0 <= cfg.search_opening <= pr2.GRIPPER_MAX_OPENING,
             f"in [0, {pr2.GRIPPER_MAX_OPENING}] m")]
