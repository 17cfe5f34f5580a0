"""The judge's record of one replayed plan: the outcome classes of Sec. III, the outcome, and
the grades that compare plans (Sec. VI-A) and score scenes (Sec. VI-B).

An `Outcome` holds the class (`OutcomeKind`), why, every box's fate, the grasp test, the
largest contact forces (N) and lags, and optionally the lift check and the robust replays'
distribution. `classify` applies Sec. III's precedence; `behaviour_grade` orders two plans'
outcomes; `scene_score` is a scene's verdict over its candidates.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from drake_clutter.evaluation.lift_check import LiftResult
from drake_clutter.evaluation.recording import Recording
from drake_clutter.evaluation.robust import RobustSummary
from drake_clutter.scene.grading import (  # noqa: F401 - re-exported: the judge's classes
    GRADE_CLASSES,
    OUTCOME_KINDS,
    OutcomeKind,
    behaviour_grade,
    classify,
)

SCENE_SCORES: tuple[str, ...] = ("success", "partial_success", "failure")


@dataclass(frozen=True)
class BoxOutcome:
    """One box after the replay: centre displacement (m, W), tilt of its z axis (rad), flags."""

    name: str
    displacement: float
    tilt: float
    fallen: bool
    tipped: bool
    final_position: tuple[float, float, float]  # m, centre in W

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"name": self.name, "displacement": self.displacement, "tilt": self.tilt,
                "fallen": self.fallen, "tipped": self.tipped,
                "final_position": list(self.final_position)}


@dataclass(frozen=True)
class GraspCheck:
    """The pre-grasp test at the end: target pose in the tool frame G and intruding boxes."""

    grasped: bool
    reason: str
    p_GT: tuple[float, float, float]  # m, target centre in G
    opening: float  # m, gap between the pads
    intruders: tuple[str, ...]  # other boxes reaching into the zone

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"grasped": self.grasped, "reason": self.reason, "p_GT": list(self.p_GT),
                "opening": self.opening, "intruders": list(self.intruders)}


@dataclass(frozen=True)
class Outcome:
    """The evaluation record of one trajectory (JSON-serialisable with `to_data`).

    ``forces`` holds the largest contact normal forces seen (N): ``arm_box`` and ``arm_static``
    (sums over a sample's contact points), ``box_static`` (one box's sum from the shelf) and the
    windowed means the thresholds use (``arm_static_mean``, ``box_static_excess_mean``, i.e.
    beyond the box's weight); ``arm_static_penetration`` is in m. ``tracking_error`` is the
    largest arm-joint lag (rad), ``finger_error`` the largest finger lag (m). ``recording``
    holds the replay's frames when `evaluate` was asked for them (``record_fps``); it is left
    out of ``to_data`` and of comparisons. ``robust`` holds the robust judge's K replays
    (`robust.RobustSummary`) when more than one was asked for; ``to_data`` writes the key only
    then, so a nominal outcome's data is as it always was.
    """

    kind: OutcomeKind
    reason: str
    boxes: tuple[BoxOutcome, ...] = ()
    grasp: GraspCheck | None = None
    forces: dict[str, float] = field(default_factory=dict)
    tracking_error: float = 0.0
    finger_error: float = 0.0
    simulated_time: float = 0.0  # s, replay plus settling
    trajectory_time: float = 0.0  # s, the plan's duration
    settled: bool = False  # the boxes came to rest before the cap
    lift: LiftResult | None = None
    wall_time: float = 0.0  # s of computer time (not part of the physics)
    recording: Recording | None = field(default=None, compare=False, repr=False)
    robust: RobustSummary | None = None

    def __post_init__(self):
        object.__setattr__(self, "kind", OutcomeKind(self.kind))

    @property
    def grasped(self) -> bool:
        """True when the target ended in the pre-grasp zone with no other box in it."""
        return self.grasp is not None and self.grasp.grasped

    def to_data(self) -> dict:
        """JSON-ready dict."""
        data = {"kind": self.kind.value, "reason": self.reason,
                "grasp": None if self.grasp is None else self.grasp.to_data(),
                "boxes": [b.to_data() for b in self.boxes], "forces": dict(self.forces),
                "tracking_error": self.tracking_error, "finger_error": self.finger_error,
                "simulated_time": self.simulated_time, "trajectory_time": self.trajectory_time,
                "settled": self.settled,
                "lift": None if self.lift is None else self.lift.to_data(),
                "wall_time": self.wall_time}
        if self.robust is not None:
            data["robust"] = self.robust.to_data()
        return data

    @staticmethod
    def from_data(data: dict) -> Outcome:
        """Inverse of `to_data` (KeyError/TypeError/ValueError on malformed data)."""
        if data["kind"] not in OUTCOME_KINDS:
            raise ValueError(f"unknown outcome kind {data['kind']!r}")
        grasp, lift, robust = data.get("grasp"), data.get("lift"), data.get("robust")
        return Outcome(
            kind=data["kind"], reason=str(data["reason"]),
            boxes=tuple(BoxOutcome(**{**b, "final_position": tuple(b["final_position"])})
                        for b in data.get("boxes", [])),
            grasp=None if grasp is None else GraspCheck(**{
                **grasp, "p_GT": tuple(grasp["p_GT"]), "intruders": tuple(grasp["intruders"])}),
            forces={k: float(v) for k, v in data.get("forces", {}).items()},
            tracking_error=float(data.get("tracking_error", 0.0)),
            finger_error=float(data.get("finger_error", 0.0)),
            simulated_time=float(data.get("simulated_time", 0.0)),
            trajectory_time=float(data.get("trajectory_time", 0.0)),
            settled=bool(data.get("settled", False)),
            lift=None if lift is None else LiftResult(
                **{**lift, "others_lifted": tuple(lift["others_lifted"])}),
            wall_time=float(data.get("wall_time", 0.0)),
            robust=None if robust is None else RobustSummary.from_data(robust))


# ----------------------------------------------------------------------------- classification


def outcome_grade(outcome: Outcome) -> tuple[int, int]:
    """`behaviour_grade` of an evaluated outcome."""
    return behaviour_grade(outcome.kind, sum(b.tipped or b.fallen for b in outcome.boxes))


def scene_score(kinds: Iterable[str]) -> str:
    """Sec. VI-B: 'success' if any candidate succeeded, 'partial_success' if the best one is a
    partial success, else 'failure' (also for no candidates)."""
    kinds = set(kinds)
    unknown = kinds - set(OUTCOME_KINDS)
    if unknown:
        raise ValueError(f"unknown outcome kinds {sorted(unknown)}")
    if "success" in kinds:
        return "success"
    return "partial_success" if "partial_success" in kinds else "failure"
