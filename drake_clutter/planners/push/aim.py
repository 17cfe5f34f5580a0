"""Push family members aimed at the boxes the straight path meets (beyond the paper).

`family.draw_member` draws via-points blind; most land where no box is. Here the via-points
are placed from the boxes that the straight path's arm enters (`obstructions`: the boxes at
rest, the planning world's capsule arm), in the approach frame at the pre-grasp: ``d`` the
approach direction (G's x axis at the last knot, made horizontal), ``side`` = z x d, z up (W).
For a met box B with centre at depth ``along`` (m along d from the pre-grasp G), sideways
``lateral`` and half extents ``half_along``, ``half_side`` (its support along d and side), a
member is one of two moves, its lengths drawn in `PushSearchConfig`'s aimed ranges:

* **aside** (push the box out of the line, then reach): G comes beside B on the side away from
  ``sign`` (B's own side of the line, or the other), moves in to B's centre depth, sweeps
  across the line by ``sign`` pushing B, then reaches along the line;
* **around** (snake past it): G holds a sideways offset that clears B on the side away from
  ``sign`` from before B's near face to past its far face, then returns to the line.

The via-points' times are spread in proportion to G's distance travelled (the path's own
duration kept), and the gripper stays closed until the last via-point with
``push_search.closed_chance``. Frames: W; metres, radians, fractions of the path's duration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import PushSearchConfig
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.push.family import PushPath, ViaPoint, draw_member
from drake_clutter.planners.tool_path import UP, ApproachFrame


@dataclass(frozen=True)
class Obstruction:
    """A box the straight path's arm enters: its name, the deepest penetration (m, > 0), and
    its centre and half extents in the approach frame at the pre-grasp (module docstring)."""

    box: str
    depth: float
    along: float
    lateral: float
    half_along: float
    half_side: float


def obstructions(geometry: ArmGeometry, straight: np.ndarray, frame: ApproachFrame,
                 target: str) -> list[Obstruction]:
    """The boxes other than ``target`` that the arm enters (signed distance < 0) at some knot
    of ``straight`` (T + 1, 8) with the boxes at rest, deepest first."""
    deepest: dict[str, float] = {}
    for q in straight:
        for c in geometry.contacts(q, max_distance=0.0, obstacles="boxes"):
            if c.obstacle != target and c.distance < 0.0:
                deepest[c.obstacle] = max(deepest.get(c.obstacle, 0.0), -c.distance)
    sizes = {b.name: np.asarray(b.size) / 2.0 for b in geometry.scene.boxes}
    found = []
    for name, depth in deepest.items():
        X = geometry.rest_pose(name)
        R, rel = X.rotation().matrix(), X.translation() - frame.positions[-1]
        found.append(Obstruction(name, depth, float(rel @ frame.d), float(rel @ frame.side),
                                 float(np.abs(R.T @ frame.d) @ sizes[name]),
                                 float(np.abs(R.T @ frame.side) @ sizes[name])))
    return sorted(found, key=lambda o: -o.depth)


def _timed(frame: ApproachFrame, points: list[tuple[float, float, float]]
           ) -> tuple[ViaPoint, ...]:
    """Via-points at (progress, lateral, vertical), timed in proportion to G's distance
    travelled from the start through them to the pre-grasp."""
    s = np.linspace(0.0, 1.0, len(frame.positions))

    def where(p, a, b):
        return np.array([np.interp(p, s, frame.positions[:, i]) for i in range(3)]) + (
            a * frame.side + b * UP)

    xs = [frame.positions[0]] + [where(*p) for p in points] + [frame.positions[-1]]
    steps = np.linalg.norm(np.diff(xs, axis=0), axis=1) + 1e-6
    times = np.cumsum(steps)[:-1] / steps.sum()
    return tuple(ViaPoint(float(t), float(p), float(a), float(b))
                 for t, (p, a, b) in zip(times, points, strict=True))


def aimed_member(rng: np.random.Generator, frame: ApproachFrame, found: list[Obstruction],
                 ranges: PushSearchConfig) -> PushPath | None:
    """A member aimed at one of the ``found`` boxes (drawn in proportion to its depth), its
    move, side and lengths drawn in ``ranges`` (module docstring); None if nothing is met."""
    if not found:
        return None
    depths = np.array([o.depth for o in found])
    o = found[int(rng.choice(len(found), p=depths / depths.sum()))]
    own = np.sign(o.lateral) or 1.0
    sign = own if rng.uniform() < ranges.own_side_chance else -own
    clear = o.half_side + ranges.gripper_half_width + rng.uniform(0.0, ranges.aim_slack)
    beside = o.lateral - sign * clear
    vertical = float(rng.uniform(ranges.vertical_low, ranges.vertical_high))
    near = frame.progress_at(o.along - o.half_along - ranges.aim_standoff
                             - rng.uniform(0.0, ranges.aim_slack))
    if rng.uniform() < ranges.aside_chance:
        centre = max(frame.progress_at(o.along + rng.uniform(-1, 1) * ranges.aim_slack), near)
        across = sign * rng.uniform(0.0, ranges.aim_slack + ranges.gripper_half_width)
        points = [(near, beside, vertical), (centre, beside, vertical),
                  (centre, across, vertical)]
    else:
        far = max(frame.progress_at(o.along + o.half_along + rng.uniform(0.0, ranges.aim_slack)),
                  near)
        points = [(near, beside, vertical), (far, beside, vertical)]
    vias = _timed(frame, points)
    open_at = vias[-1].knot if rng.uniform() < ranges.closed_chance else 0.0
    return PushPath(vias, open_at)


def draw(rng: np.random.Generator, frame: ApproachFrame, found: list[Obstruction],
         ranges: PushSearchConfig) -> PushPath:
    """A member: aimed (`aimed_member`) with ``ranges.aimed_chance`` when a box is met, else
    drawn blind (`family.draw_member`)."""
    if found and ranges.aimed_chance > 0.0 and rng.uniform() < ranges.aimed_chance:
        return aimed_member(rng, frame, found, ranges)
    return draw_member(rng, ranges)
