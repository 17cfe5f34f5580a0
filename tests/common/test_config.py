"""Configuration: defaults carry the paper's constants; YAML and command-line overrides."""

from __future__ import annotations

import pytest

from drake_clutter.common.config import Config, ConfigError, config_from_data, load_config


def test_defaults_hold_the_paper_clutter_levels():
    config = load_config()
    assert config.generator.bookshelf.clutter_levels == (1, 5, 10, 15, 20, 25)
    assert config.generator.fridge.clutter_levels == (1, 2, 4, 6, 8, 10, 12, 14, 16)
    assert config.generator.scenes_per_level == 10
    assert config.generator.bookshelf.wall_thickness is None
    assert config.generator.fridge.wall_thickness == 0.02


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


def _config_source(name: str = "config"):
    """The source of one of the configuration's modules (`config`, `physics_config`)."""
    import importlib

    module = importlib.import_module(f"drake_clutter.common.{name}")
    with open(module.__file__, encoding="utf-8") as handle:
        return handle.read()


def _comments(source):
    """(line number, text) of every comment token in ``source``."""
    import io
    import tokenize

    return [(token.start[0], token.string)
            for token in tokenize.generate_tokens(io.StringIO(source).readline)
            if token.type == tokenize.COMMENT]


def _dataclass_fields(tree):
    import ast

    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and any(
                "dataclass" in ast.unparse(decorator) for decorator in node.decorator_list):
            for statement in node.body:
                if isinstance(statement, ast.AnnAssign):
                    yield node.name, statement


def _comment_rule_violations(source):
    """Each field: exactly one comment line directly above it, none on its own lines; no issue
    numbers or README pointers in any comment or docstring."""
    import ast
    import re

    tree = ast.parse(source)
    lines = source.splitlines()
    comment_lines = {line for line, _ in _comments(source)}
    problems = []
    fields = list(_dataclass_fields(tree))
    for class_name, node in fields:
        name = f"{class_name}.{ast.unparse(node.target)}"
        above = node.lineno - 1  # 1-based number of the line above the field
        if not lines[above - 1].strip().startswith("#"):
            problems.append(f"{name}: no comment line directly above")
        elif lines[above - 2].strip().startswith("#"):
            problems.append(f"{name}: more than one comment line above")
        if comment_lines & set(range(node.lineno, node.end_lineno + 1)):
            problems.append(f"{name}: a comment on the field's own line(s)")
    texts = [text for _, text in _comments(source)]
    texts += [ast.get_docstring(node) or "" for node in ast.walk(tree)
              if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef))]
    for text in texts:
        if re.search(r"\bissue\s*#?\d+", text, re.IGNORECASE) or "README" in text:
            problems.append(f"cites an issue or the README: {text!r}")
    return problems


def test_every_config_field_has_one_comment_line_above_it_and_no_history():
    """What, unit and source above each field; the reasons live in docs/decisions.md."""
    import ast
    import dataclasses
    import importlib

    found = declared = 0
    for name in ("config", "physics_config"):
        source = _config_source(name)
        assert _comment_rule_violations(source) == [], name
        found += len(list(_dataclass_fields(ast.parse(source))))
        module = importlib.import_module(f"drake_clutter.common.{name}")
        declared += sum(len(dataclasses.fields(c)) for c in vars(module).values()
                        if dataclasses.is_dataclass(c) and c.__module__ == module.__name__)
    assert found == declared > 200  # the rule saw every section's fields


def test_the_comment_rule_catches_a_trailing_comment_and_an_issue_number():
    source = _config_source()
    trailing = source.replace("time_step: float = bounded(0.01, ge=1e-5)\n",
                              "time_step: float = bounded(0.01, ge=1e-5)  # s\n", 1)
    assert trailing != source
    assert any("own line" in p for p in _comment_rule_violations(trailing))
    cited = source.replace("(phi steps knot_time / substeps), s; ours", "(issue #3)", 1)
    assert cited != source
    assert any("issue" in p for p in _comment_rule_violations(cited))


@pytest.mark.parametrize("low, high", [("knot_low", "knot_high"),
                                       ("progress_low", "progress_high")])
def test_push_ranges_must_be_ordered(low, high):
    with pytest.raises(ConfigError,
                       match=f"push_search.{high}: must be at least push_search.{low}"):
        load_config(None, [f"push_search.{low}=0.8", f"push_search.{high}=0.5"])
    config = load_config(None, [f"push_search.{low}=0.5", f"push_search.{high}=0.5"])
    assert getattr(config.push_search, high) == 0.5


def _integer_fields_without_an_upper_end(cls, seen=None) -> list[str]:
    """Every integer field (tuples of integers too) under the dataclass ``cls`` whose declared
    bounds have no upper end."""
    import dataclasses
    import typing

    from drake_clutter.common.accepts import field_bounds

    seen = set() if seen is None else seen
    if cls in seen:
        return []
    seen.add(cls)
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        kinds = [a for a in (typing.get_args(hints[f.name]) or (hints[f.name],))
                 if a is not type(None)]
        for kind in kinds:
            if dataclasses.is_dataclass(kind):
                out += _integer_fields_without_an_upper_end(kind, seen)
        if int in kinds or hints[f.name] == tuple[int, ...]:
            bounds = field_bounds(f)
            if bounds is None or (bounds.le is None and bounds.lt is None):
                out.append(f"{cls.__name__}.{f.name}")
    return out


def test_every_count_has_an_upper_end():
    """A count typed by mistake (phi_judge.members=1000000) is refused at load."""
    from drake_clutter.common.config import Config

    assert _integer_fields_without_an_upper_end(Config) == []
    with pytest.raises(ConfigError, match=r"phi_judge.members: must be in \[1, 256\]"):
        load_config(None, ["phi_judge.members=1000000"])
    with pytest.raises(ConfigError, match="physics.time_budget: must be in"):
        load_config(None, ["physics.time_budget=1e9"])
    with pytest.raises(ConfigError, match="baseline.num_knots"):
        load_config(None, ["baseline.num_knots=100000"])


def test_the_upper_end_rule_sees_a_count_without_one():
    import dataclasses

    from drake_clutter.common.accepts import bounded

    @dataclasses.dataclass(frozen=True)
    class Counts:
        capped: int = bounded(1, ge=1, le=10)
        open_ended: int = bounded(1, ge=1)
        levels: tuple[int, ...] = bounded((1,), ge=1)

    assert _integer_fields_without_an_upper_end(Counts) == ["Counts.open_ended",
                                                            "Counts.levels"]


# ----------------------------------------------------------------------- settings by owner


@pytest.mark.parametrize("old, new", [("physics.grasp_heights", "starts.grasp_heights"),
                                      ("push_search.members", "phi_judge.members"),
                                      ("ensemble.judge_hold_knots", "phi_judge.hold_knots"),
                                      ("dynamics.jam_depth", "phi_judge.jam_depth"),
                                      ("push.lateral", "push_search.lateral")])
def test_a_moved_field_under_its_old_name_is_one_line_naming_the_new(old, new, tmp_path,
                                                                      capsys):
    from drake_clutter.cli import main

    section, name = old.split(".")
    value = "[0.7]" if name == "grasp_heights" else "2"
    with pytest.raises(ConfigError, match=f"{old}: renamed to {new}"):
        load_config(None, [f"{old}={value}"])
    path = tmp_path / "old.yaml"
    path.write_text(f"{section}:\n  {name}: {value}\n")
    assert main(["config", "show", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{old}: renamed to {new}" in err and len(err.strip().splitlines()) == 1


def test_a_removed_section_names_where_its_fields_went():
    with pytest.raises(ConfigError, match="unknown key .*; its fields moved to phi_judge"):
        config_from_data({"ensemble": {"not_a_field": 1}})


def test_a_stored_configuration_of_the_old_layout_reads_as_today():
    from drake_clutter.common.config import config_to_data, upgrade_stored

    today = config_to_data(Config())
    old = {k: dict(v) if isinstance(v, dict) else v for k, v in today.items()}
    for name in ("grasp_heights", "side_tolerance"):
        old["physics"][name] = old["starts"].pop(name)
    old["ensemble"] = {"members": 1, "seed": 7, "judge_hold_knots": 3}
    old["push_search"]["members"] = old["phi_judge"].pop("members")
    old["dynamics"]["jam_depth"] = 0.002
    old["push"] = {"lateral": 0.2}
    upgraded = config_from_data(upgrade_stored(old))
    assert upgraded.starts == Config().starts
    assert upgraded.phi_judge.members == 4  # the search's members, not ensemble.members 1
    assert (upgraded.phi_judge.seed, upgraded.phi_judge.hold_knots) == (7, 3)
    assert upgraded.phi_judge.jam_depth == 0.002 and upgraded.push_search.lateral == 0.2
    assert upgrade_stored(today) == today
