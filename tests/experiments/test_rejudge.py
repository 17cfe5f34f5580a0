"""Re-judging a store's plans under changed judge settings: same plans, new rows, no planning."""

from __future__ import annotations

import pytest

from drake_clutter.common.config import ConfigError
from drake_clutter.experiments.executors import run_experiment
from drake_clutter.experiments.rejudge import rejudge
from drake_clutter.experiments.specs import load_spec
from drake_clutter.experiments.store import Store
from drake_clutter.testing.specs import TINY_SPEC

TINY = TINY_SPEC


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rejudge")
    spec_file = folder / "tiny.yaml"
    spec_file.write_text(TINY, encoding="utf-8")
    spec, path = load_spec(str(spec_file))
    db = folder / "source.db"
    run_experiment(spec, path, db, workers=1, progress=False)
    return db


def test_rejudged_rows_keep_the_plans_and_gain_the_robust_judge(source, tmp_path):
    out = tmp_path / "robust.db"
    summary = rejudge(str(source), str(out), ["evaluation.robust_replays=3"], workers=1,
                      progress=False)
    assert summary["ran"] == 2 and summary["skipped"] == 0
    with Store(source, create=False) as store:
        before = {(r["scene"], r["angle"]): r for r in store.rows()}
    with Store(out, create=False) as store:
        after = {(r["scene"], r["angle"]): r for r in store.rows()}
        configs = store.configurations()
    assert set(after) == set(before)
    for key, row in after.items():
        old = before[key]
        assert row["plan"] == old["plan"] and row["kind"] == old["kind"]  # the nominal replay
        assert row["config_name"] == old["config_name"]
        assert row["config_hash"] != old["config_hash"]
        kinds = row["outcome"]["robust"]["kinds"]
        assert row["robust_replays"] == len(kinds) == 3 and kinds[0] == row["kind"]
        assert row["p_success"] == kinds.count("success") / 3
        assert row["timings"]["plan"] == old["timings"]["plan"]
        assert configs[row["config_hash"]]["config"]["evaluation"]["robust_replays"] == 3
    again = rejudge(str(source), str(out), ["evaluation.robust_replays=3"], workers=1,
                    progress=False)
    assert again["ran"] == 0 and again["skipped"] == 2  # resumable


def test_only_judge_settings_can_change(source, tmp_path):
    with pytest.raises(ConfigError) as err:
        rejudge(str(source), str(tmp_path / "x.db"), ["physics.iterations=40"], progress=False)
    assert err.value.field == "physics.iterations"
    assert not (tmp_path / "x.db").exists()


def test_a_configuration_stored_before_the_judge_in_phi_had_its_section_is_read():
    from drake_clutter.common.config import Config, config_to_data
    from drake_clutter.experiments.rejudge import changed_config

    old = config_to_data(Config())
    old["push_search"]["members"] = old["phi_judge"].pop("members")
    old["ensemble"] = {"members": 1, "judge_hold_knots": old["phi_judge"].pop("hold_knots")}
    old["physics"]["grasp_heights"] = old["starts"].pop("grasp_heights")
    config = changed_config(old, ["evaluation.max_static_force=75"])
    assert config.phi_judge == Config().phi_judge and config.starts == Config().starts
    assert config.evaluation.max_static_force == 75


def test_a_raised_force_limit_replays_only_the_kinematic_failures(source, tmp_path):
    lazy = rejudge(str(source), str(tmp_path / "lazy.db"), ["evaluation.max_static_force=150"],
                   workers=1, progress=False)
    full = rejudge(str(source), str(tmp_path / "full.db"), ["evaluation.max_static_force=150"],
                   workers=1, progress=False, carry_unaffected=False)
    with Store(source, create=False) as store:
        before = {(r["scene"], r["angle"]): r for r in store.rows()}
    failures = sum(r["kind"] == "kinematic_failure" for r in before.values())
    assert lazy["carried"] == len(before) - failures and full["carried"] == 0
    with Store(tmp_path / "lazy.db", create=False) as a, \
            Store(tmp_path / "full.db", create=False) as b:
        lazy_rows = {(r["scene"], r["angle"]): r for r in a.rows()}
        full_rows = {(r["scene"], r["angle"]): r for r in b.rows()}
    for key, row in lazy_rows.items():
        assert row["outcome"] == full_rows[key]["outcome"]  # the replay would give it back
        assert row["config_hash"] == full_rows[key]["config_hash"] != before[key]["config_hash"]


@pytest.mark.parametrize(("changed", "kinds", "carried"), [
    ({"max_static_force": 150.0}, ["success", "failure_to_grasp"], True),
    ({"max_static_force": 150.0}, ["success", "kinematic_failure"], False),
    ({"max_static_force": 30.0}, ["success", "success"], False),  # lowered: may now fail
    ({"max_tilt": 0.5}, ["success", "success"], False),  # a class taken at the end
    ({}, ["success", "success"], False),
])
def test_which_rows_a_changed_judge_leaves_as_they_were(changed, kinds, carried):
    from drake_clutter.experiments.rejudge import unaffected

    stored = {"max_static_force": 50.0, "max_tilt": 0.35, "robust_replays": 2}
    row = {"outcome": {"kind": kinds[0], "robust": {"kinds": kinds}}}
    assert unaffected(row, stored, {**stored, **changed}) is carried
