"""Every configuration field declares what it accepts, and loading refuses anything else: a
walk over every field of every section, through the command line."""

from __future__ import annotations

import dataclasses
import json
import typing
from dataclasses import replace

import pytest

from drake_clutter import cli
from drake_clutter.common.accepts import Bounds, bounded, field_bounds, violations
from drake_clutter.common.config import Config, ConfigError, Range, check_config, load_config
from drake_clutter.robot import pr2


def _leaves(cls, prefix=""):
    """(dotted path, dataclass field, type) of every leaf field under ``cls``; a `Range` is a
    leaf (its bounds are its field's)."""
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        path = f"{prefix}.{f.name}" if prefix else f.name
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp) and tp is not Range:
            yield from _leaves(tp, path)
        else:
            yield path, f, tp


LEAVES = list(_leaves(Config))


def _default(path):
    value = Config()
    for part in path.split("."):
        value = getattr(value, part)
    return value


def _numeric(tp) -> bool:
    """Whether a field of type ``tp`` holds numbers (int / float, in tuples, optional, Range)."""
    if tp is Range:
        return True
    if tp in (int, float):
        return True
    return any(_numeric(a) for a in typing.get_args(tp) if a is not Ellipsis)


def _outside(bounds: Bounds, integer: bool):
    """A number just outside ``bounds`` (None when it has no end)."""
    if bounds.gt is not None:
        return bounds.gt
    if bounds.ge is not None:
        return bounds.ge - 1 if integer else bounds.ge - 0.5
    if bounds.lt is not None:
        return bounds.lt
    if bounds.le is not None:
        return bounds.le + 1 if integer else bounds.le + 0.5
    return None


def _with_first(value, bad):
    """``value`` (a number, a tuple - possibly nested or empty - or a Range) with its first
    number replaced by ``bad``."""
    if isinstance(value, Range):
        return {"low": bad, "high": value.high}
    if isinstance(value, tuple):
        if not value:
            return [bad]
        return [_with_first(value[0], bad), *[dataclasses.asdict(v) if isinstance(v, Range)
                                               else v for v in value[1:]]]
    return bad


def _bad_value(path, f, tp):
    """A value the field must refuse: outside its declared range, else of the wrong type."""
    bounds = field_bounds(f)
    if bounds is not None and bounds.bounded:
        integer = int in (tp, *typing.get_args(tp)) or "int" in str(tp)
        return _with_first(_default(path), _outside(bounds, integer))
    if tp is bool:
        return "maybe"
    if typing.get_origin(tp) is typing.Literal:
        return "no-such-choice"
    return "not-a-number" if _numeric(tp) else 3


def test_the_defaults_pass():
    check_config(Config())
    assert load_config(None) == Config()
    assert cli.main(["config", "show"]) == 0


def test_every_numeric_field_declares_its_range():
    """A field holding numbers carries `accepts.bounded` (no bound at all only where any
    finite number is meaningful, e.g. a camera offset)."""
    missing = [path for path, f, tp in LEAVES if _numeric(tp) and field_bounds(f) is None]
    assert missing == []
    unbounded = [path for path, f, tp in LEAVES
                 if field_bounds(f) is not None and not field_bounds(f).bounded]
    assert unbounded == ["viz.camera_offset"]
    assert len(LEAVES) > 250


@pytest.mark.parametrize("path, f, tp", LEAVES, ids=[p for p, _, _ in LEAVES])
def test_a_value_outside_a_field_s_range_is_refused_in_one_line(path, f, tp, capsys):
    """Every field, through the command line: exit status 2, one line naming the field, and
    nothing written to stdout."""
    bad = _bad_value(path, f, tp)
    assert cli.main(["config", "show", "--set", f"{path}={json.dumps(bad)}"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert f": {path}" in err, (bad, err)


@pytest.mark.parametrize("overrides, field, reason", [
    (["physics.sphere_iterations=50"], "physics.sphere_iterations", "at most iterations (0)"),
    (["physics.iterations=30", "physics.sphere_iterations=40"], "physics.sphere_iterations",
     "at most iterations (30)"),
    (["baseline.alpha_min=0.5", "baseline.alpha_max=0.2"], "baseline.alpha_max",
     "above alpha_min"),
    (["baseline.ik_min_distance=0.03"], "baseline.ik_min_distance", "below d_safe"),
    (["baseline.opt_control_points=40"], "baseline.opt_control_points", "num_knots"),
    (["physics.control_points=3"], "physics.control_points", "opt_spline_order"),
    (["evaluation.monitor_interval=500", "evaluation.force_window=1"],
     "evaluation.monitor_interval", "control period"),
    (["evaluation.force_window=0.001"], "evaluation.force_window", "control period"),
    (["generator.target_depth.high=0.5"], "generator.target_depth", "boards' depth"),
    (["generator.boxes.height.low=0.3"], "generator.boxes.height.high", "at least low"),
    (["dynamics.contact_model=point", "dynamics.derivative_method=autodiff"],
     "dynamics.derivative_method", "'point'"),
    (["world.contact_approximation=lagged", "dynamics.derivative_method=hybrid"],
     "dynamics.derivative_method", "'fd'"),
])
def test_relations_between_fields_are_refused_at_load(overrides, field, reason):
    with pytest.raises(ConfigError) as info:
        load_config(None, overrides)
    assert info.value.field == field
    assert reason in info.value.reason


def test_a_configuration_built_in_code_is_checked_by_check_config():
    config = Config()
    bad = replace(config, evaluation=replace(config.evaluation, sim_dt=-1.0))
    with pytest.raises(ConfigError, match="evaluation.sim_dt"):
        check_config(bad)
    with pytest.raises(ConfigError, match="evaluation.sim_dt"):
        check_config(bad.evaluation, section="evaluation")


def test_a_yaml_file_names_itself_and_the_field(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("dynamics:\n  substeps: 0\n")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.file == str(path) and info.value.field == "dynamics.substeps"


def test_the_robot_s_limits_match_the_configuration_s_bounds():
    """The configuration cannot import the robot package; its copies of the robot's facts are
    checked here."""
    world = {f.name: f for f in dataclasses.fields(Config().world)}
    assert field_bounds(world["park_gripper_opening"]).le == pr2.GRIPPER_MAX_OPENING
    hints = typing.get_type_hints(type(Config().physics))
    assert typing.get_args(hints["post_variant"]) == pr2.VARIANTS
    assert len(Config().world.park_configuration) == len(pr2.ARM_JOINTS)


def test_bounds_read_in_words_and_walk_tuples_and_ranges():
    @dataclasses.dataclass(frozen=True)
    class Section:
        a: float = bounded(1.0, gt=0.0, le=2.0)
        b: tuple[int, ...] = bounded((1, 2), ge=1)
        c: Range = bounded(Range(0.1, 0.2), gt=0.0)
        d: float | None = bounded(None, ge=0.0)

    assert violations(Section()) == []
    assert violations(Section(a=3.0)) == [("a", "must be in (0, 2], got 3.0")]
    assert violations(Section(b=(1, 0))) == [("b", "must be at least 1, got (1, 0)")]
    assert violations(Section(c=Range(-0.1, 0.2)))[0][0] == "c"
    assert violations(Section(d=-1.0)) == [("d", "must be non-negative, got -1.0")]
    assert violations(Range(0.3, 0.2)) == [("high", "must be at least low (0.3), got 0.2")]


def test_a_field_of_the_wrong_type_built_in_code_is_refused():
    config = Config()
    with pytest.raises(ConfigError, match="evaluation.robust_seed: must be an integer"):
        check_config(replace(config, evaluation=replace(config.evaluation, robust_seed=1.5)))
    with pytest.raises(ConfigError, match="physics.box_qp: must be true or false"):
        check_config(replace(config, physics=replace(config.physics, box_qp=1)))
