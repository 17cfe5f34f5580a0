"""Robot trajectories, planner candidates and plan files: the data that flows between stages.

A `Trajectory` is a joint-space path of the PR2 arm and gripper sampled at knots: ``times``
(s, increasing, starting at 0) and ``q`` (one row per knot) over `TRAJECTORY_JOINTS`: the seven
arm joints (rad) followed by the gripper opening (m, gap between the pads, 0..0.09). Between
knots the path is linear in these coordinates. `robot_positions` turns rows into the 9-vector
the Drake worlds use (ROBOT_JOINTS: 7 arm joints + 2 finger slides).

A `Candidate` is what a planner returns per approach angle (Sec. IV): the angle, a status and
reason, the trajectory (if any) and timings. A plan file (JSON) holds the candidates of one
scene; `save_plan` / `load_plan` write and read it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import numpy as np
from pydrake.math import BsplineBasis, KnotVectorType

from drake_clutter.common.config import EvaluationConfig
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.robot import pr2

GRIPPER_COORDINATE = "r_gripper_opening"
TRAJECTORY_JOINTS: tuple[str, ...] = pr2.ARM_JOINTS + (GRIPPER_COORDINATE,)
PLAN_FORMAT = "drake_clutter.plan/1"


class PlanFileError(InputError):
    """A plan file is unreadable or malformed."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Knot times (s, shape (T,)) and positions (shape (T, 8), TRAJECTORY_JOINTS order)."""

    times: np.ndarray
    q: np.ndarray
    joint_names: tuple[str, ...] = TRAJECTORY_JOINTS

    def __post_init__(self):
        times = np.asarray(self.times, dtype=float)
        q = np.asarray(self.q, dtype=float)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "q", q)
        if times.ndim != 1 or len(times) < 2:
            raise ValueError("a trajectory needs at least two knot times")
        if q.shape != (len(times), len(self.joint_names)):
            expected = (len(times), len(self.joint_names))
            raise ValueError(f"q has shape {q.shape}, expected {expected}")
        if np.any(np.diff(times) <= 0) or not np.all(np.isfinite(times)):
            raise ValueError("knot times must be finite and strictly increasing")
        if not np.all(np.isfinite(q)):
            raise ValueError("joint positions must be finite")

    def __eq__(self, other) -> bool:
        return (isinstance(other, Trajectory) and self.joint_names == other.joint_names
                and np.array_equal(self.times, other.times) and np.array_equal(self.q, other.q))

    @property
    def duration(self) -> float:
        """s."""
        return float(self.times[-1] - self.times[0])

    @property
    def num_knots(self) -> int:
        """Number of knots T."""
        return len(self.times)

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Positions at time(s) ``t`` (linear between knots, held outside the time span)."""
        t = np.asarray(t, dtype=float)
        cols = [np.interp(t, self.times, self.q[:, j]) for j in range(self.q.shape[1])]
        return np.stack(cols, axis=-1)

    def resampled(self, dt: float) -> Trajectory:
        """The same path sampled every ``dt`` seconds (the last knot kept exactly)."""
        n = max(1, math.ceil(self.duration / dt - 1e-9))
        times = np.linspace(self.times[0], self.times[-1], n + 1)
        return Trajectory(times, self.at(times), self.joint_names)

    def robot_positions(self) -> np.ndarray:
        """Rows as Drake robot position vectors, shape (T, 9), ROBOT_JOINTS order."""
        return robot_positions(self.q)

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"joint_names": list(self.joint_names), "times": self.times.tolist(),
                "q": self.q.tolist()}

    @staticmethod
    def from_data(data: dict) -> Trajectory:
        """Inverse of `to_data`; raises ValueError/KeyError/TypeError on bad data."""
        return Trajectory(np.asarray(data["times"], dtype=float),
                          np.asarray(data["q"], dtype=float), tuple(data["joint_names"]))


def robot_positions(q_traj: np.ndarray) -> np.ndarray:
    """(…, 8) TRAJECTORY_JOINTS rows -> (…, 9) ROBOT_JOINTS rows (both fingers at half the gap)."""
    q_traj = np.asarray(q_traj, dtype=float)
    finger = q_traj[..., -1:] / 2.0
    return np.concatenate([q_traj[..., :-1], finger, finger], axis=-1)


def trajectory_coordinates(q_robot: np.ndarray) -> np.ndarray:
    """(…, 9) ROBOT_JOINTS rows -> (…, 8) TRAJECTORY_JOINTS rows (opening = sum of the slides)."""
    q_robot = np.asarray(q_robot, dtype=float)
    return np.concatenate([q_robot[..., :7], q_robot[..., 7:8] + q_robot[..., 8:9]], axis=-1)


class CandidateStatus(StrEnum):
    """What became of one approach angle (the value is what plan files and stores hold)."""

    OK = "ok"  # a usable trajectory
    IK_FAILED = "ik_failed"  # no IK solution for the start or the pre-grasp pose (Sec. IV)
    OPTIMISATION_FAILED = "optimisation_failed"  # the solver failed or lost the pre-grasp pose
    COLLISION_CHECK_FAILED = "collision_check_failed"  # the dense shelf check found penetration
    PLANNER_FAILURE = "planner_failure"  # the planner produced nothing


CANDIDATE_STATUSES: tuple[str, ...] = tuple(s.value for s in CandidateStatus)


@dataclass
class Candidate:
    """One approach angle's result: ``alpha`` (rad), its `CandidateStatus` (a plain string is
    converted; an unknown one raises ValueError), why, the trajectory and timings (s)."""

    alpha: float
    status: CandidateStatus
    reason: str = ""
    trajectory: Trajectory | None = None
    planner: str = "baseline"
    timings: dict[str, float] = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    # its approach angle's index among `approach.approach_angles` (seeds IK and the search);
    # None for a hand-made candidate. Not written by `to_data`: a stored row has its ``angle``.
    index: int | None = field(default=None, compare=False)

    def __post_init__(self):
        self.status = CandidateStatus(self.status)

    @property
    def ok(self) -> bool:
        """True when the candidate carries a usable trajectory."""
        return self.status == CandidateStatus.OK and self.trajectory is not None

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"alpha": self.alpha, "status": self.status.value, "reason": self.reason,
                "planner": self.planner, "timings": dict(self.timings),
                "details": self.details,
                "trajectory": None if self.trajectory is None else self.trajectory.to_data()}

    @staticmethod
    def from_data(data: dict) -> Candidate:
        """Inverse of `to_data`."""
        traj = data.get("trajectory")
        return Candidate(alpha=float(data["alpha"]), status=str(data["status"]),
                         reason=str(data.get("reason", "")),
                         trajectory=None if traj is None else Trajectory.from_data(traj),
                         planner=str(data.get("planner", "baseline")),
                         timings={k: float(v) for k, v in data.get("timings", {}).items()},
                         details=dict(data.get("details", {})))


def save_plan(path: str | Path, scene_name: str, candidates: list[Candidate],
              extra: dict | None = None) -> Path:
    """Writes a plan file (JSON) with the candidates of one scene; returns the path."""
    path = Path(path)
    doc = {"format": PLAN_FORMAT, "scene": scene_name, **(extra or {}),
           "candidates": [c.to_data() for c in candidates]}
    try:
        path.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    except OSError as exc:
        raise PlanFileError(path, "", f"cannot write the plan file: {exc.strerror}") from None
    return path


def load_plan(path: str | Path) -> tuple[str, list[Candidate], dict]:
    """Reads a plan file: (scene name, candidates, the whole document). Raises PlanFileError."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise PlanFileError(path, "", "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PlanFileError(path, "", f"cannot be read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise PlanFileError(path, f"line {exc.lineno}", f"not valid JSON: {exc.msg}") from None
    if not isinstance(doc, dict) or doc.get("format") != PLAN_FORMAT:
        raise PlanFileError(path, "format", f"not a plan file (expected format {PLAN_FORMAT})")
    candidates = []
    for i, item in enumerate(doc.get("candidates", [])):
        try:
            candidates.append(Candidate.from_data(item))
        except (KeyError, TypeError, ValueError) as exc:
            raise PlanFileError(path, f"candidates[{i}]", f"malformed candidate: {exc}") from None
    return str(doc.get("scene", "")), candidates, doc


def plan_limit_violation(trajectory: Trajectory, config: EvaluationConfig) -> str:
    """"" when the plan stays within the PR2's joint position and velocity limits and the
    gripper's range, else the first violation (the arm cannot follow it: kinematic failure)."""
    if trajectory.joint_names != TRAJECTORY_JOINTS:
        raise ValueError(f"trajectory joints {trajectory.joint_names} are not "
                         f"{TRAJECTORY_JOINTS}")
    tol = config.joint_limit_tolerance
    q, t = trajectory.q, trajectory.times
    for j, (name, (lo, hi)) in enumerate(pr2.arm_joint_limits().items()):
        bad = np.flatnonzero((q[:, j] < lo - tol) | (q[:, j] > hi + tol))
        if bad.size:
            return (f"{name} at {q[bad[0], j]:.3f} rad (knot {bad[0]}) leaves its limits "
                    f"[{lo:.3f}, {hi:.3f}]")
    opening = q[:, -1]
    bad = np.flatnonzero((opening < -tol) | (opening > pr2.GRIPPER_MAX_OPENING + tol))
    if bad.size:
        return f"gripper opening {opening[bad[0]]:.4f} m (knot {bad[0]}) outside its range"
    speeds = np.abs(np.diff(q[:, :7], axis=0)) / np.diff(t)[:, None]
    limits = pr2.velocity_limits()
    for j, name in enumerate(pr2.ARM_JOINTS):
        allowed = config.velocity_limit_factor * limits[name]
        bad = np.flatnonzero(speeds[:, j] > allowed)
        if bad.size:
            return (f"{name} moves at {speeds[bad[0], j]:.2f} rad/s (after knot {bad[0]}), "
                    f"above its {allowed:.2f} rad/s limit")
    return ""


def spline_basis(num_knots: int, num_points: int, order: int) -> np.ndarray:
    """(num_knots, num_points) values of a clamped uniform B-spline basis of ``order`` at
    ``num_knots`` evenly spaced parameters: knot values = basis @ control points. The first
    and last rows pick the first and last control points."""
    basis = BsplineBasis(order, num_points, KnotVectorType.kClampedUniform, 0.0, 1.0)
    s = np.linspace(0.0, 1.0, num_knots)
    return np.array([[basis.EvaluateBasisFunctionI(i, x) for i in range(num_points)]
                     for x in s])
