"""Seeded perturbations of a scene's boxes: the worlds of the robust judge and of phi's ensemble.

Every box's position (x, y on the board, m) and yaw (rad) are moved by uniform draws within
half-ranges, its density (so its mass) and friction coefficient scaled by 1 + a uniform draw
within relative half-ranges. A moved box that would overlap another box or leave the board
(walls included) is drawn again, up to ``RETRIES`` times, then left at its nominal pose; its
mass and friction are perturbed all the same. The generator is seeded with the caller's seed
sequence, so the same seed always gives the same world.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from drake_clutter.scene.scenes import BoxObject, Scene, fits_on_shelf, footprints_overlap

RETRIES = 20  # draws of a box's pose before it keeps its nominal one


@dataclass(frozen=True)
class BoxPerturbation:
    """Half-ranges of the uniform draws: position (m, each of x and y), yaw (rad), mass and
    friction (relative, below 1)."""

    position: float
    yaw: float
    mass: float
    friction: float


def _moved(box: BoxObject, rng: np.random.Generator, ranges: BoxPerturbation) -> BoxObject:
    x, y, yaw = box.pose
    d = ranges.position
    return replace(box, pose=(x + rng.uniform(-d, d), y + rng.uniform(-d, d),
                              yaw + rng.uniform(-ranges.yaw, ranges.yaw)))


def perturb_boxes(scene: Scene, ranges: BoxPerturbation, seed: Sequence[int]) -> Scene:
    """The scene with every box moved and its density and friction scaled within ``ranges``
    (world frame poses, see the module docstring), drawn from ``default_rng(seed)``."""
    rng = np.random.default_rng(list(seed))
    boxes: list[BoxObject] = list(scene.boxes)
    for i, box in enumerate(scene.boxes):
        density = box.density * (1 + rng.uniform(-ranges.mass, ranges.mass))
        friction = box.friction * (1 + rng.uniform(-ranges.friction, ranges.friction))
        others = [b.footprint() for j, b in enumerate(boxes) if j != i]
        placed = box
        for _ in range(RETRIES):
            candidate = _moved(box, rng, ranges)
            corners = candidate.footprint()
            if fits_on_shelf(candidate, scene.shelf) and not any(
                    footprints_overlap(corners, other) for other in others):
                placed = candidate
                break
        boxes[i] = replace(placed, density=density, friction=friction)
    return replace(scene, boxes=tuple(boxes))
