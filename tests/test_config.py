"""Configuration: defaults carry the paper's constants; YAML and command-line overrides."""

from __future__ import annotations

import pytest

from drake_clutter.common.config import ConfigError, load_config


def test_defaults_hold_the_paper_clutter_levels():
    config = load_config()
    assert config.generator.bookshelf.clutter_levels == (1, 5, 10, 15, 20, 25)
    assert config.generator.fridge.clutter_levels == (1, 2, 4, 6, 8, 10, 12, 14, 16)
    assert config.generator.scenes_per_level == 10
    assert config.generator.bookshelf.wall_thickness is None
    assert config.generator.fridge.wall_thickness is not None


def test_yaml_then_command_line_overrides(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("world:\n  time_step: 0.005\ngenerator:\n  boxes:\n    height: {low: 0.1, "
                    "high: 0.2}\n")
    config = load_config(path, ["world.time_step=0.002", "generator.fridge.board_width=0.7"])
    assert config.world.time_step == 0.002
    assert config.generator.boxes.height.low == 0.1
    assert config.generator.fridge.board_width == 0.7
    assert config.generator.bookshelf.board_width == load_config().generator.bookshelf.board_width


@pytest.mark.parametrize("text,field", [("world:\n  time_stepp: 1\n", "world.time_stepp"),
                                        ("world:\n  time_step: fast\n", "world.time_step"),
                                        ("[1, 2]\n", ""),
                                        ("world: {\n", "line")])
def test_bad_config_files(tmp_path, text, field):
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(path) in str(info.value) and info.value.field.startswith(field)


@pytest.mark.parametrize("item", ["world.time_step", "nope.x=1", "world.time_step=abc",
                                  "world=3"])
def test_bad_overrides(item):
    with pytest.raises(ConfigError):
        load_config(None, [item])


def test_scientific_notation_is_a_number_in_files_and_overrides(tmp_path):
    """PyYAML (YAML 1.1) reads 1e-4 without a dot as a string; float fields take it."""
    path = tmp_path / "c.yaml"
    path.write_text("dynamics:\n  fd_step: 1e-5\nworld:\n  hydroelastic_modulus: 5E5\n")
    config = load_config(path, ["physics.w_force=1e-2"])
    assert config.dynamics.fd_step == 1e-5
    assert config.world.hydroelastic_modulus == 5e5
    assert config.physics.w_force == 0.01
    with pytest.raises(ConfigError):  # integers stay integers
        load_config(None, ["physics.iterations=1e1"])
    with pytest.raises(ConfigError):  # and words are not numbers
        load_config(None, ["physics.w_force=1e-2x"])
