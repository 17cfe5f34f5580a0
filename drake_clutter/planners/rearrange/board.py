"""The board model of the rearrange planner: the boxes as footprints on the shelf's board, each
with a planar offset from its resting place, pushed rigidly (a box that a pushed box meets is
shoved ahead of it along the same direction, a chain); and the region the final reach needs.

The region to clear is the final reach's swept arm: the capsule arm at the reach's last
``rearrange.region_knots`` knots (1: the pre-grasp pose alone) with the gripper open as there.
A box other than the target that it enters by more than ``rearrange.deep`` must be moved
before the reach (Dogar & Srinivasa's negative goal region). Geometry only: no friction, no
tipping; phi judges what the pushes really do.
Frames: W; metres, radians.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydrake.math import RigidTransform

from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.tool_path import ARM
from drake_clutter.scene.scenes import BoxObject, Scene, fits_on_shelf, footprints_overlap

Offsets = dict[str, np.ndarray]  # box name -> planar offset (2,) from its resting place, W


class Board:
    """The scene's boxes on the board, pushed as rigid footprints; ``chain``: the most boxes
    one push may move (the pushed box included)."""

    def __init__(self, scene: Scene, chain: int):
        self.scene, self.chain = scene, chain
        self.boxes = {b.name: b for b in scene.boxes}

    def moved(self, name: str, offset: np.ndarray) -> BoxObject:
        """The box ``name`` at its resting pose shifted by ``offset`` (2,) in W."""
        box = self.boxes[name]
        x, y, yaw = box.pose
        return replace(box, pose=(x + float(offset[0]), y + float(offset[1]), yaw))

    def push(self, offsets: Offsets, name: str, shift: np.ndarray, depth: int = 0
             ) -> Offsets | None:
        """Offsets after box ``name`` moves by ``shift`` (2,) more, every box it then overlaps
        pushed ahead of it along the same direction as far as it must; None where the move
        pushes the target, leaves a footprint off the board or in a wall, or moves more than
        ``chain`` boxes. Only the end of the shift is checked: a caller sweeping a box steps
        it (the search by ``rearrange.step``)."""
        new = dict(offsets)
        new[name] = new.get(name, np.zeros(2)) + shift
        box = self.moved(name, new[name])
        if not fits_on_shelf(box, self.scene.shelf):
            return None
        corners = box.footprint()
        u = shift / np.linalg.norm(shift)
        for other in self.boxes:
            if other == name or not footprints_overlap(
                    corners, self.moved(other, new.get(other, np.zeros(2))).footprint()):
                continue
            if other == self.scene.target or depth + 1 >= self.chain:
                return None
            need = self._clearing(corners, other, new.get(other, np.zeros(2)), u)
            new = self.push(new, other, need * u, depth + 1)
            if new is None:
                return None
        return new

    def _clearing(self, corners: np.ndarray, other: str, offset: np.ndarray,
                  u: np.ndarray) -> float:
        """The least travel (m) of box ``other`` along ``u`` that parts its footprint from
        ``corners`` (bisection to 0.1 mm)."""
        lo, hi = 0.0, 0.05
        while footprints_overlap(corners, self.moved(other, offset + hi * u).footprint()):
            hi *= 2.0
        while hi - lo > 1e-4:
            mid = 0.5 * (lo + hi)
            if footprints_overlap(corners, self.moved(other, offset + mid * u).footprint()):
                lo = mid
            else:
                hi = mid
        return hi


def moved_boxes(before: Offsets, after: Offsets) -> list[str]:
    """The boxes whose offsets differ (by more than 1 um) between ``before`` and ``after``."""
    return [k for k in after
            if np.linalg.norm(after[k] - before.get(k, np.zeros(2))) > 1e-6]


def world_poses(geometry: ArmGeometry, offsets: Offsets) -> dict[str, RigidTransform]:
    """X_WB of every box: its resting pose translated by its offset (2,) in W."""
    poses = {}
    for box in geometry.scene.boxes:
        X = geometry.rest_pose(box.name)
        shift = offsets.get(box.name, np.zeros(2))
        poses[box.name] = RigidTransform(X.rotation(),
                                         X.translation() + [shift[0], shift[1], 0.0])
    return poses


def entered(geometry: ArmGeometry, q: np.ndarray, poses: dict[str, RigidTransform],
            skip: frozenset[str] = frozenset()) -> dict[str, float]:
    """Depth (m, > 0) by which the capsule arm at ``q`` (8,) enters each box (boxes at
    ``poses``), those in ``skip`` left out."""
    found: dict[str, float] = {}
    for c in geometry.contacts(q, poses, max_distance=0.0, obstacles="boxes"):
        if c.obstacle not in skip and c.distance < 0.0:
            found[c.obstacle] = max(found.get(c.obstacle, 0.0), -c.distance)
    return found


def box_distance(geometry: ArmGeometry, q: np.ndarray, poses: dict[str, RigidTransform],
                 box: str, reach: float) -> float:
    """The capsule arm's signed distance (m) at ``q`` (8,) to ``box`` (boxes at ``poses``);
    ``reach`` where it is farther than ``reach`` (m)."""
    found = [c.distance for c in geometry.contacts(q, poses, max_distance=reach,
                                                   obstacles="boxes") if c.obstacle == box]
    return min(found, default=reach)


def reach_region(reach: np.ndarray, knots: int = 0) -> np.ndarray:
    """The knots (K, 8) whose swept arm is the region to clear: the reach's last ``knots``
    (0: all of them; 1: the pre-grasp pose), the gripper open as at its last knot."""
    region = np.array(reach[-knots:] if knots else reach, dtype=float)
    region[:, ARM] = region[-1, ARM]
    return region


def crowding(geometry: ArmGeometry, region: np.ndarray, offsets: Offsets, deep: float
             ) -> dict[str, float]:
    """The boxes other than the target that the region's arm (`reach_region`) enters by more
    than ``deep`` (m) with the boxes at ``offsets``: name -> the deepest entry (m)."""
    return crowding_at(geometry, region, world_poses(geometry, offsets), deep)


def crowding_at(geometry: ArmGeometry, region: np.ndarray, poses: dict[str, RigidTransform],
                deep: float) -> dict[str, float]:
    """`crowding` with the boxes at ``poses`` (X_WB of every box, e.g. where phi left them)."""
    target = frozenset([geometry.scene.target])
    deepest: dict[str, float] = {}
    for q in region:
        for name, depth in entered(geometry, q, poses, target).items():
            deepest[name] = max(deepest.get(name, 0.0), depth)
    return {k: v for k, v in deepest.items() if v > deep}
