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
    with pytest.raises(ConfigError, match=f"push.{high}: must be at least push.{low}"):
        load_config(None, [f"push.{low}=0.8", f"push.{high}=0.5"])
    assert getattr(load_config(None, [f"push.{low}=0.5", f"push.{high}=0.5"]).push, high) == 0.5


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
    """A count typed by mistake (push_search.members=1000000) is refused at load."""
    from drake_clutter.common.config import Config

    assert _integer_fields_without_an_upper_end(Config) == []
    with pytest.raises(ConfigError, match=r"push_search.members: must be in \[1, 256\]"):
        load_config(None, ["push_search.members=1000000"])
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
