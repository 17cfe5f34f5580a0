"""The robust judge (beyond the paper): one plan replayed in K seeded perturbations of its world.

One Bullet replay is one sample of a chaotic outcome (moving every knot by 1e-6 rad changes the
class of some plans). The robust judge replays a plan K times: replay 0 in the scene as it is
(Sec. III's nominal outcome, unchanged), replays 1..K-1 in `perturbed_scene` s, where every
box's initial position and yaw, mass and friction are moved by uniform draws within the
``evaluation.robust_*`` half-ranges. Replay k of a scene always meets the same perturbation
(the generator is seeded with ``[robust_seed, k]``), whatever the plan: two planners' plans of
one scene are compared in the same K worlds (common random numbers).

The draw is `scene.perturbation.perturb_boxes` (a box that would overlap another or leave the
board is drawn again, then left at its nominal pose). `RobustSummary` holds the K classes and
grades and what they give: P(success), P(success or partial success), the expected grade class.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.scene.perturbation import BoxPerturbation, perturb_boxes
from drake_clutter.scene.scenes import Scene


@dataclass(frozen=True)
class RobustSummary:
    """The classes and grades (`outcome.behaviour_grade`) of K replays, the nominal first."""

    seed: int
    kinds: tuple[str, ...]
    grades: tuple[tuple[int, int], ...]

    @property
    def replays(self) -> int:
        """K, the number of replays."""
        return len(self.kinds)

    @property
    def p_success(self) -> float:
        """Fraction of the replays that are a success."""
        return sum(k == "success" for k in self.kinds) / self.replays

    @property
    def p_success_or_partial(self) -> float:
        """Fraction of the replays that are a success or a partial success."""
        return sum(k in ("success", "partial_success") for k in self.kinds) / self.replays

    @property
    def expected_grade(self) -> float:
        """Mean grade class over the replays (0 success .. 4 no plan; lower is better)."""
        return sum(g[0] for g in self.grades) / self.replays

    def to_data(self) -> dict:
        """JSON-ready dict (the derived probabilities included, for readers of the files)."""
        return {"seed": self.seed, "kinds": list(self.kinds),
                "grades": [list(g) for g in self.grades], "p_success": self.p_success,
                "p_success_or_partial": self.p_success_or_partial,
                "expected_grade": self.expected_grade}

    @staticmethod
    def from_data(data: dict) -> RobustSummary:
        """Inverse of `to_data` (KeyError/TypeError/ValueError on malformed data)."""
        kinds = tuple(str(k) for k in data["kinds"])
        grades = tuple((int(a), int(b)) for a, b in data["grades"])
        if not kinds or len(kinds) != len(grades):
            raise ValueError(f"{len(kinds)} kinds for {len(grades)} grades")
        return RobustSummary(int(data["seed"]), kinds, grades)




def perturbed_scene(scene: Scene, config: EvaluationConfig, replay: int) -> Scene:
    """The scene of robust replay ``replay`` (0: the scene itself): every box moved and its
    density and friction scaled within the ``robust_*`` half-ranges, seeded by
    ``[config.robust_seed, replay]`` (see the module docstring)."""
    if replay == 0:
        return scene
    ranges = BoxPerturbation(config.robust_position, config.robust_yaw, config.robust_mass,
                             config.robust_friction)
    return perturb_boxes(scene, ranges, [config.robust_seed, replay])


def summarise(seed: int, kinds: Sequence[str], grades: Sequence[tuple[int, int]]
              ) -> RobustSummary:
    """The RobustSummary of K replays' classes and grades, the nominal first."""
    return RobustSummary(seed, tuple(str(k) for k in kinds), tuple(tuple(g) for g in grades))
