"""Scene generators (Sec. VI-B): determinism, clutter levels, density, named sets."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import GeneratorConfig
from drake_clutter.scene.generators import (
    SceneSpec,
    board_coverage,
    free_spots,
    generate_scene,
    scene_set,
    shoulder_xy,
)
from drake_clutter.scene.scenes import footprints_overlap, save_scene, validate_scene


def _assert_inside_and_disjoint(scene):
    x0, x1, y0, y1 = scene.shelf.interior_bounds()
    corners = [b.footprint() for b in scene.boxes]
    for c in corners:
        assert c[:, 0].min() >= x0 and c[:, 0].max() <= x1
        assert c[:, 1].min() >= y0 and c[:, 1].max() <= y1
    for i in range(len(corners)):
        for j in range(i + 1, len(corners)):
            assert not footprints_overlap(corners[i], corners[j], tol=0.0)


def test_same_seed_gives_byte_identical_file(tmp_path):
    a = save_scene(generate_scene("bookshelf", 15, seed=11), tmp_path / "a.yaml")
    b = save_scene(generate_scene("bookshelf", 15, seed=11), tmp_path / "b.yaml")
    assert a.read_bytes() == b.read_bytes()
    c = save_scene(generate_scene("bookshelf", 15, seed=12), tmp_path / "c.yaml")
    assert a.read_bytes() != c.read_bytes()


@pytest.mark.parametrize("kind,n", [("bookshelf", 25), ("fridge", 16)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_densest_levels_fit_and_are_dense(kind, n, seed):
    scene = generate_scene(kind, n, seed)
    assert len(scene.boxes) == n
    _assert_inside_and_disjoint(scene)
    validate_scene(scene)
    assert board_coverage(scene) > 0.30
    # Nearly full: a median-sized (7 cm) box finds (almost) no free spot left, against
    # thousands of spots with 5 boxes.
    assert free_spots(scene, 0.07) < 100
    assert free_spots(generate_scene(kind, 5, seed), 0.07) > 1000


def test_target_is_within_reach_region():
    config = GeneratorConfig()
    for seed in range(20):
        scene = generate_scene("bookshelf", 10, seed)
        t = scene.target_box
        depth = t.pose[0] - scene.shelf.front_x
        assert config.target_depth.low <= depth <= config.target_depth.high
        shoulder_y = shoulder_xy(scene.robot)[1]
        assert abs(t.pose[1] - shoulder_y) <= config.target_lateral
        assert max(t.size[:2]) <= config.target.footprint.high


def test_sampled_values_lie_in_documented_ranges():
    config = GeneratorConfig()
    scene = generate_scene("fridge", 16, seed=5)
    for box in scene.boxes[1:]:
        r = config.boxes
        assert r.footprint.low <= min(box.size[:2]) and max(box.size[:2]) <= r.footprint.high
        assert r.height.low <= box.size[2] <= r.height.high
        assert r.density.low <= box.density <= r.density.high
        assert r.friction.low <= box.friction <= r.friction.high
    assert all(b.size[2] < scene.shelf.walls.height for b in scene.boxes)


def test_paper_set_has_150_scenes_at_the_paper_levels():
    specs = scene_set("paper")
    assert len(specs) == 150 and len({s.seed for s in specs}) == 150
    levels = sorted({(s.kind, s.num_objects) for s in specs})
    assert [n for k, n in levels if k == "bookshelf"] == [1, 5, 10, 15, 20, 25]
    assert [n for k, n in levels if k == "fridge"] == [1, 2, 4, 6, 8, 10, 12, 14, 16]


def test_every_clutter_level_generates():
    config = GeneratorConfig()
    for kind, env in (("bookshelf", config.bookshelf), ("fridge", config.fridge)):
        coverages = [board_coverage(generate_scene(kind, n, 3)) for n in env.clutter_levels]
        assert np.all(np.diff(coverages) > 0), "more boxes cover more of the board"


def test_bad_arguments():
    with pytest.raises(ValueError, match="at least 1"):
        generate_scene("bookshelf", 0, 1)
    with pytest.raises(ValueError, match="unknown shelf kind"):
        generate_scene("cupboard", 3, 1)
    with pytest.raises(ValueError, match="unknown scene set"):
        scene_set("everything")


def test_a_generated_scene_name_gives_back_its_spec():
    for spec in scene_set("paper")[::17]:
        assert SceneSpec.from_name(spec.name) == spec
    assert SceneSpec.from_name("fig5_large_small") is None
    assert SceneSpec.from_name("bookshelf_n10_s7x") is None
