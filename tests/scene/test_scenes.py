"""Scene model: YAML round trip, validation errors, fuzzing."""

from __future__ import annotations

import copy

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_clutter.common.typed_yaml import to_data
from drake_clutter.scene.generators import generate_scene
from drake_clutter.scene.scenes import (
    SceneError,
    load_scene,
    load_shipped_scene,
    save_scene,
    scene_from_data,
    scene_from_text,
    scene_to_text,
    shipped_scene_names,
)


@pytest.fixture(scope="module")
def scene():
    return generate_scene("fridge", 6, seed=7)


@pytest.fixture()
def data(scene):
    return to_data(scene)


def test_yaml_round_trip_is_exact(scene, tmp_path):
    path = save_scene(scene, tmp_path / "s.yaml")
    loaded = load_scene(path)
    assert loaded == scene
    assert scene_to_text(loaded) == path.read_text()


@pytest.mark.parametrize("name", shipped_scene_names())
def test_shipped_scenes_load_and_round_trip(name, tmp_path):
    scene = load_shipped_scene(name)
    assert scene.description, "every shipped scene states its intended situation"
    again = load_scene(save_scene(scene, tmp_path / f"{name}.yaml"))
    assert again == scene


def test_representative_scenes_are_shipped():
    names = set(shipped_scene_names())
    assert {"fig5_large_small", "fig6_push_sideways", "fig7_cascade", "fig8_snaking",
            "default_bookshelf", "default_fridge", "dense_rearrange"} <= names


def _error(data, file="bad.yaml") -> SceneError:
    with pytest.raises(SceneError) as info:
        scene_from_data(data, file)
    return info.value


def test_overlapping_boxes(data):
    data["boxes"][1]["pose"] = list(data["boxes"][0]["pose"])
    err = _error(data)
    assert err.file == "bad.yaml" and err.field == "boxes[1].pose" and "overlap" in err.reason


def test_box_off_the_board():
    scene = generate_scene("bookshelf", 3, seed=1)
    data = to_data(scene)
    data["boxes"][2]["pose"][0] = scene.shelf.front_x - 0.01
    err = _error(data)
    assert err.field == "boxes[2].pose" and "off the board" in err.reason


def test_box_inside_a_wall(data, scene):
    x0, x1, y0, y1 = scene.shelf.interior_bounds()
    data["boxes"] = data["boxes"][:1]
    data["boxes"][0]["pose"] = [x1, (y0 + y1) / 2, 0.0]
    err = _error(data)
    assert err.field == "boxes[0].pose" and "inside a wall" in err.reason
    assert "back wall" in err.reason


@pytest.mark.parametrize("field,value", [("size", [0.05, 0.0, 0.1]), ("size", [-0.1, 0.05, 0.1]),
                                         ("density", 0.0), ("density", -5)])
def test_non_positive_sizes_and_densities(data, field, value):
    data["boxes"][0][field] = value
    err = _error(data)
    assert err.field.startswith(f"boxes[0].{field}") and "positive" in err.reason


def test_missing_target(data):
    del data["target"]
    err = _error(data)
    assert err.field == "target" and "missing" in err.reason


def test_unknown_target(data):
    data["target"] = "no_such_box"
    err = _error(data)
    assert err.field == "target" and "names no box" in err.reason


@pytest.mark.parametrize("where", ["top", "shelf", "box"])
def test_unknown_keys(data, where):
    node = {"top": data, "shelf": data["shelf"], "box": data["boxes"][0]}[where]
    node["colour_of_sky"] = "blue"
    err = _error(data)
    assert err.field.endswith("colour_of_sky") and "unknown key" in err.reason


@pytest.mark.parametrize("path,value", [(("shelf", "depth"), "deep"), (("boxes", 0, "size"), 3),
                                        (("robot", "torso_height"), [1]), (("name",), 5),
                                        (("boxes", 0, "pose"), [1, 2]),
                                        (("shelf", "kind"), "cupboard")])
def test_wrong_types(data, path, value):
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    err = _error(data)
    assert err.field.startswith(str(path[0])) and err.reason


def test_unreadable_yaml_names_file_and_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: x\nshelf: [unclosed\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(path) in str(info.value) and "line" in info.value.field
    assert "unreadable YAML" in info.value.reason


def test_missing_file(tmp_path):
    with pytest.raises(SceneError, match="no such file"):
        load_scene(tmp_path / "nope.yaml")


def test_not_a_mapping():
    with pytest.raises(SceneError, match="mapping"):
        scene_from_text("- 1\n- 2\n")


def test_duplicate_names_and_bad_torso(data):
    bad = copy.deepcopy(data)
    bad["boxes"][1]["name"] = bad["boxes"][0]["name"]
    assert "duplicate" in _error(bad).reason
    bad = copy.deepcopy(data)
    bad["robot"]["torso_height"] = 0.5
    assert _error(bad).field == "robot.torso_height"


def test_bookshelf_with_walls_and_fridge_without(data):
    bad = copy.deepcopy(data)
    bad["shelf"]["kind"] = "bookshelf"
    assert _error(bad).field == "shelf.walls"
    bad = copy.deepcopy(data)
    bad["shelf"]["walls"] = None
    assert _error(bad).field == "shelf.walls"


def test_box_taller_than_fridge(data):
    data["boxes"][0]["size"][2] = data["shelf"]["walls"]["height"] + 0.01
    assert "taller" in _error(data).reason


# ----------------------------------------------------------------------------- fuzzing

_scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5),
                     st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5))
_values = st.recursive(_scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(st.text(max_size=6), children, max_size=4)),
    max_leaves=12)


def _mutations(base):
    """Strategies that replace one node of a valid scene document with junk."""
    paths = []

    def walk(node, path):
        paths.append(path)
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, path + (k,))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, path + (i,))

    walk(base, ())
    return st.tuples(st.sampled_from(paths[1:]), _values, st.booleans())


_BASE = to_data(generate_scene("fridge", 4, seed=3))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_mutations(_BASE))
def test_fuzzed_documents_only_raise_scene_error(mutation):
    path, value, delete = mutation
    doc = copy.deepcopy(_BASE)
    node = doc
    for key in path[:-1]:
        node = node[key]
    if delete and isinstance(node, dict):
        del node[path[-1]]
    else:
        node[path[-1]] = value
    try:
        scene_from_data(doc, "fuzz.yaml")
    except SceneError as err:
        assert str(err).startswith("fuzz.yaml: ")


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_fuzzed_text_only_raises_scene_error(text):
    """200 random characters are never a scene (it needs a name, shelf, target and boxes)."""
    with pytest.raises(SceneError, match="^fuzz.yaml"):
        scene_from_text(text, "fuzz.yaml")


@settings(max_examples=100, deadline=None)
@given(_values)
def test_fuzzed_yaml_values_only_raise_scene_error(value):
    """A random YAML value of a dozen leaves is never a scene."""
    with pytest.raises(SceneError, match="^fuzz.yaml"):
        scene_from_text(yaml.safe_dump(value), "fuzz.yaml")
