"""A path family that can push (beyond the paper): the straight approach bent through via-points.

The baseline reaches along a straight line into the pre-grasp (Sec. IV); where a box stands in
that line the arm can only go around it or move it. A member of this family starts from a
straight path q (T + 1, 8; the baseline's at some grasp height and yaw) and moves the tool frame
G through up to a few via-points before the pre-grasp. Each via-point says, at a fraction of the
path's duration (``knot``): how far along the straight path G has come (``progress``, 0 the
start, 1 the pre-grasp), and how far G stands off it sideways (``lateral``, m along the
horizontal normal to the approach, W) and up (``vertical``, m along W's z). Between the start,
the via-points and the pre-grasp each of the three is linear in time. So:

* a lateral or vertical sweep: one via-point off the line, back on it before the pre-grasp;
* a push-aside: two via-points at about the same progress on either side of the line (the
  gripper sweeps a box out of the line, then reaches);
* a pause: two via-points with the same progress and offset.

``open_at`` (a fraction of the duration, 0 for "as the straight path") keeps the gripper
closed to ``closed_opening`` before it and opens it over the next knots: a closed gripper is
narrower between boxes. The start knot and the pre-grasp knot are the straight path's own.

The joint path follows G's targets knot by knot: at each knot the straight path's
configuration at the same progress (linearly interpolated between its knots) is the seed, and
damped Gauss-Newton steps on the pose error (position and orientation; the orientation is the
straight path's at that progress) bring G onto the target (`tool_path.follow_targets`). A member is
feasible when every knot converged, the joints stay in their limits and speeds
(`trajectory.plan_limit_violation`, the judge's own check), and the arm clears the shelf
(`clearance.dense_check`). Frames: W the world, G the tool frame; metres, radians, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import Config, PushSearchConfig
from drake_clutter.planners.clearance import ShelfClearance, judge_feasible
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.tool_path import ARM, follow_targets

POSE_LIMIT = 1e-3  # m or rad: a member whose knots miss their targets by more is dropped


@dataclass(frozen=True)
class ViaPoint:
    """One via-point: at fraction ``knot`` of the duration, G at fraction ``progress`` of the
    straight path, ``lateral`` m sideways of it and ``vertical`` m above it."""

    knot: float
    progress: float
    lateral: float = 0.0
    vertical: float = 0.0


@dataclass(frozen=True)
class PushPath:
    """A family member: the via-points (in time order) and when the gripper opens (fraction
    of the duration; 0: as the straight path)."""

    vias: tuple[ViaPoint, ...] = ()
    open_at: float = 0.0

    def to_data(self) -> dict:
        """JSON-ready dict."""
        return {"vias": [[v.knot, v.progress, v.lateral, v.vertical] for v in self.vias],
                "open_at": self.open_at}


def profiles(member: PushPath, num_knots: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(progress, lateral, vertical) at the knots 0..T (T = num_knots - 1): linear in time
    between (0: 0, 0, 0), the via-points and (T: 1, 0, 0)."""
    times = np.r_[0.0, [v.knot for v in member.vias], 1.0]
    if np.any(np.diff(times) < 0):
        raise ValueError(f"via-points out of time order: {times.tolist()}")
    t = np.linspace(0.0, 1.0, num_knots)
    columns = [np.r_[0.0, [getattr(v, f) for v in member.vias], end]
               for f, end in (("progress", 1.0), ("lateral", 0.0), ("vertical", 0.0))]
    return tuple(np.interp(t, times, c) for c in columns)


def _at_progress(q: np.ndarray, s: float) -> np.ndarray:
    """The straight path q (T + 1, 8) at progress s (0..1), linear between knots."""
    x = s * (len(q) - 1)
    i = min(int(np.floor(x)), len(q) - 2)
    lam = x - i
    return (1.0 - lam) * q[i] + lam * q[i + 1]


def member_path(geometry: ArmGeometry, straight: np.ndarray, member: PushPath,
                closed_opening: float = 0.0, opening_knots: int = 3
                ) -> tuple[np.ndarray, float]:
    """The knot path (T + 1, 8) of ``member`` about the straight path ``straight`` (same
    knots; its first and last knots kept exactly) and the largest pose error of its knots (m or
    rad). See the module docstring; the gripper ramps from ``closed_opening`` (m) to the
    straight path's opening over ``opening_knots`` knots from ``open_at``."""
    straight = np.asarray(straight, dtype=float)
    n = len(straight)
    progress, lateral, vertical = profiles(member, n)
    seeds = np.array([_at_progress(straight, s) for s in progress])
    poses = [geometry.tool_jacobian(q)[0] for q in seeds]
    d = geometry.tool_axis(straight[-1], 0)[0]  # the approach direction at the pre-grasp
    side = np.cross([0.0, 0.0, 1.0], d)
    side /= np.linalg.norm(side)
    targets = np.array([X.translation() + a * side + b * np.array([0.0, 0.0, 1.0])
                        for X, a, b in zip(poses, lateral, vertical, strict=True)])
    rotations = np.array([X.rotation().matrix() for X in poses])
    inner = slice(1, n - 1)
    path = seeds.copy()
    path[inner], worst = follow_targets(geometry, seeds[inner], targets[inner], rotations[inner])
    path[0], path[-1] = straight[0], straight[-1]
    if member.open_at > 0.0:
        first = int(round(member.open_at * (n - 1)))
        ramp = np.clip((np.arange(n) - first) / max(opening_knots, 1), 0.0, 1.0)
        path[:, ARM] = closed_opening + ramp * (straight[:, ARM] - closed_opening)
        path[-1, ARM] = straight[-1, ARM]
    return path, worst


def draw_member(rng: np.random.Generator, ranges: PushSearchConfig) -> PushPath:
    """A random member with ``ranges.vias`` via-points: times and progresses sorted uniform
    draws, offsets uniform in their ranges; the gripper closed until a uniform time with
    ``closed_chance``."""
    vias = ranges.vias
    knots = np.sort(rng.uniform(ranges.knot_low, ranges.knot_high, vias))
    progress = np.sort(rng.uniform(ranges.progress_low, ranges.progress_high, vias))
    lateral = rng.uniform(-ranges.lateral, ranges.lateral, vias)
    vertical = rng.uniform(ranges.vertical_low, ranges.vertical_high, vias)
    open_at = (float(rng.uniform(0.3, 0.8)) if rng.uniform() < ranges.closed_chance else 0.0)
    return PushPath(tuple(ViaPoint(float(k), float(p), float(a), float(b))
                          for k, p, a, b in zip(knots, progress, lateral, vertical,
                                                strict=True)), open_at)



def feasible(q: np.ndarray, error: float, times: np.ndarray, clearance: ShelfClearance,
             config: Config) -> bool:
    """Whether a member's knots (T + 1, 8, at ``times`` s) reached their targets within
    ``POSE_LIMIT`` (``error``, m or rad), keep the judge's joint and speed limits and pass the
    baseline's dense shelf check (`clearance.judge_feasible`)."""
    return error <= POSE_LIMIT and judge_feasible(q, times, clearance, config)
