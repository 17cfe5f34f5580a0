"""Seeded perturbations of a scene's boxes (the robust judge's and phi's ensemble's worlds)."""

from __future__ import annotations

import numpy as np

from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.perturbation import BoxPerturbation, perturb_boxes
from drake_clutter.scene.scenes import validate_scene

RANGES = BoxPerturbation(position=0.003, yaw=0.05, mass=0.2, friction=0.2)


def test_same_seed_same_world_within_the_ranges():
    scene = generate_scene("fridge", 10, 4015)
    nominal = {b.name: b for b in scene.boxes}
    world = perturb_boxes(scene, RANGES, [7, 1])
    validate_scene(world)
    assert world == perturb_boxes(scene, RANGES, [7, 1])
    assert world != perturb_boxes(scene, RANGES, [7, 2])
    assert world != perturb_boxes(scene, RANGES, [8, 1])
    moved = 0
    for box in world.boxes:
        ref = nominal[box.name]
        shift = np.subtract(box.pose[:2], ref.pose[:2])
        assert np.all(np.abs(shift) <= RANGES.position + 1e-12)
        assert abs(box.pose[2] - ref.pose[2]) <= RANGES.yaw + 1e-12
        assert 0 < abs(box.density / ref.density - 1) <= RANGES.mass + 1e-12
        assert 0 < abs(box.friction / ref.friction - 1) <= RANGES.friction + 1e-12
        moved += bool(np.any(shift != 0))
    assert moved >= len(world.boxes) // 2  # most boxes find room to move


def test_zero_ranges_leave_the_scene_as_it_is():
    scene = generate_scene("bookshelf", 10, 2015)
    assert perturb_boxes(scene, BoxPerturbation(0.0, 0.0, 0.0, 0.0), [3, 1]) == scene
