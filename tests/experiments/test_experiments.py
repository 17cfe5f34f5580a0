"""Experiment specs, tiers, work units, the unit worker and the executors (Sec. VI-B)."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import pytest

from drake_clutter.cli import main
from drake_clutter.common.config import load_config
from drake_clutter.experiments.executors import (
    DEAD_WORKER_REASON,
    format_summary,
    run_experiment,
    run_local,
    run_ray,
)
from drake_clutter.experiments.specs import (
    TIERS,
    SpecError,
    config_hash,
    expand,
    failure_result,
    load_spec,
    resolve_config,
    run_unit,
    split_wall_times,
)
from drake_clutter.experiments.store import Store
from drake_clutter.planners.budget import Deadline
from drake_clutter.scene.generators import scene_set
from drake_clutter.testing.specs import TINY_SPEC

CRASH_SCENE = "crash_me"


def _write(tmp_path, text: str, name: str = "spec.yaml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


TINY = TINY_SPEC


def test_tiers_load_and_expand():
    counts = {}
    for tier in TIERS:
        spec, path = load_spec(tier)
        assert path.endswith(f"{tier}.yaml")
        units = expand(spec, path)
        assert len({u.key for u in units}) == len(units)  # no duplicate keys
        counts[tier] = len(units)
    # Sec. VI-B: 150 scenes x 14 angles, both planners.
    assert counts["paper"] == 150 * 14 * 2
    assert counts["smoke"] == 4 * 2 * 2
    assert counts["smoke"] < counts["small"] < counts["paper"]
    assert counts["behaviours"] == 4 * 6 * 2  # scenes x angles x planners
    assert counts["probe"] == 24 * 4 * 2  # scenes x angles x planners
    assert counts["paper_protocol"] == 24 * 14 * 2  # the probe's scenes x all 14 angles
    assert counts["probe_half"] == 24 * 2 * 2
    assert counts["heldout"] == 24 * 2 * 2
    assert counts["candidates"] == 4 * 6 * 15  # scenes x angles x configurations


@pytest.mark.parametrize("path", sorted(
    (Path(__file__).resolve().parents[2] / "docs" / "specs").glob("*.yaml")),
    ids=lambda p: p.name)
def test_the_documented_specs_load_and_expand(path):
    """Every measurement spec the docs name loads, checks and expands to distinct units,
    each configuration resolving to its own configuration hash."""
    spec, file = load_spec(path)
    units = expand(spec, file)
    assert units and len({u.key for u in units}) == len(units)
    hashes = {name: config_hash(resolve_config(spec, name, file)) for name in spec.configurations}
    assert len(set(hashes.values())) == len(hashes)


def test_the_tiers_compare_the_default_planners():
    from drake_clutter.planners.registry import COMPARED

    for tier in TIERS:
        spec, _ = load_spec(tier)
        assert tuple(spec.planners) == (("baseline",) if tier == "candidates" else COMPARED), tier


def test_heldout_tier_shares_no_scene_with_the_probe_tier():
    probe, heldout = ({u.scene for u in expand(*load_spec(t))} for t in ("probe", "heldout"))
    assert len(heldout) == 24 and not probe & heldout
    assert heldout <= {s.name for s in scene_set("paper")}


def test_probe_tier_draws_paper_scenes_at_four_levels_per_environment_robustly():
    spec, path = load_spec("probe")
    units = expand(spec, path)
    paper = {s.name for s in scene_set("paper")}
    assert {u.scene for u in units} <= paper
    levels = {(u.kind, u.num_objects) for u in units}
    assert len([k for k, _ in levels if k == "bookshelf"]) == 4
    assert len([k for k, _ in levels if k == "fridge"]) == 4
    config = resolve_config(spec, "defaults", path)
    assert config.evaluation.robust_replays == 8
    protocol, ppath = load_spec("paper_protocol")
    assert {u.scene for u in expand(protocol, ppath)} == {u.scene for u in units}
    assert resolve_config(protocol, "defaults", ppath).evaluation.robust_replays == 8
    behaviours, bpath = load_spec("behaviours")
    assert resolve_config(behaviours, "defaults", bpath).evaluation.robust_replays == 8


def test_small_tier_covers_every_clutter_level():
    spec, path = load_spec("small")
    levels = {(u.kind, u.num_objects) for u in expand(spec, path)}
    config = load_config()
    assert levels == ({("bookshelf", n) for n in config.generator.bookshelf.clutter_levels}
                      | {("fridge", n) for n in config.generator.fridge.clutter_levels})


def test_spec_units_and_hash(tmp_path):
    spec, path = load_spec(_write(tmp_path, TINY))
    units = expand(spec, path)
    assert [(u.scene, u.planner, u.angle) for u in units] == [
        ("bookshelf_n01_s2015", "baseline", 4), ("bookshelf_n01_s2015", "baseline", 9)]
    # The hash is the resolved configuration's: an override to the default value changes
    # nothing, a real change gives another hash.
    default = config_hash(load_config(None, ["dynamics.workers=0"]))
    assert units[0].config_hash == default
    same = config_hash(load_config(None, ["dynamics.workers=0", "baseline.num_angles=14"]))
    other = config_hash(load_config(None, ["dynamics.workers=0", "baseline.num_angles=12"]))
    assert same == default != other
    drawing = config_hash(load_config(None, ["dynamics.workers=0", "viz.fps=10"]))
    assert drawing == default  # drawing settings cannot change a row


@pytest.mark.parametrize("text,field,needle", [
    (TINY + "colour: red\n", "colour", "unknown key"),
    (TINY.replace("[baseline]", "[rrt]"), "planners[0]", "must be one of"),
    (TINY.replace("[4, 9]", "[4, 14]"), "angles", "index 14 outside"),
    (TINY + "scene_set: everything\n", "scene_set", "unknown scene set"),
    (TINY.replace("[dynamics.workers=0]", "[dynamics.wrokers=0]"),
     "overrides (dynamics.wrokers)", "unknown key"),
    (TINY + "configurations: {a: [], b: [baseline.num_angles=14]}\n", "configurations.b",
     "the same settings as configuration 'a'"),
    (TINY + "configurations: {few: [physics.iterations=-1]}\n",
     "configurations.few (physics.iterations)", "in [0, 100000]"),
    (TINY + "configurations: {few: [evaluation.max_tilt=-1]}\n",
     "configurations.few (evaluation.max_tilt)", "in (0, 1.5708)"),
    (TINY.replace("[dynamics.workers=0]", "[evaluation.sim_dt=-1]"),
     "overrides (evaluation.sim_dt)", "in [1e-05, 0.01]"),
    (TINY.replace("levels: [1]", "levels: [0]"), "generated[0].levels", "in [1, 40]"),
    (TINY.replace("levels: [1]", "levels: [1000]"), "generated[0].levels", "in [1, 40]"),
    (TINY.replace("levels: [1]", "levels: []"), "generated[0].levels", "at least one level"),
    (TINY.replace("seeds: [2015]", "seeds: [2015, -1]"), "generated[0].seeds", "in [0, 4.29"),
    ("name: x\nplanners: [baseline]\n", "scene_set", "name some scenes"),
    (TINY + "ray_max_retries: -1\n", "ray_max_retries", "in [0, 10]"),
    (TINY + "ray_max_retries: 1000\n", "ray_max_retries", "in [0, 10]"),
    (TINY + "scenes_per_level: 100000\n", "scenes_per_level", "in [0, 10000]"),
])
def test_bad_spec_names_file_and_field(tmp_path, text, field, needle):
    path = _write(tmp_path, text)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert info.value.field == field and needle in info.value.reason
    assert str(path) in str(info.value)


def test_a_spec_with_a_judge_setting_out_of_range_writes_nothing(tmp_path, capsys):
    """A bad override is refused before any unit runs: no store is created."""
    path = _write(tmp_path, TINY + "configurations: {bad: [evaluation.sim_dt=-1]}\n")
    db = tmp_path / "r.db"
    assert main(["experiment", "run", str(path), "--db", str(db)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "evaluation.sim_dt" in err
    assert not db.exists()


def test_a_spec_whose_boxes_do_not_fit_writes_nothing(tmp_path, capsys):
    """A level the board cannot hold fails when the run starts, before a store exists."""
    text = TINY.replace("{kind: bookshelf, levels: [1], seeds: [2015]}",
                        "{kind: bookshelf, levels: [1], seeds: [2015]}\n"
                        "  - {kind: fridge, levels: [40], seeds: [7]}")
    path = _write(tmp_path, text + "configurations: {few: [generator.max_attempts=1, "
                                   "generator.max_redraws_per_box=2]}\n")
    db = tmp_path / "r.db"
    assert main(["experiment", "run", str(path), "--db", str(db)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "generated[1]" in err and "40 boxes" in err
    assert not db.exists()


def test_bad_spec_on_the_command_line_is_one_line_and_exit_2(tmp_path, capsys):
    path = _write(tmp_path, TINY.replace("[4, 9]", "[4, 99]"))
    assert main(["experiment", "run", str(path), "--db", str(tmp_path / "r.db")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and "angles" in err
    assert main(["experiment", "run", "no_such_tier", "--db", str(tmp_path / "r.db")]) == 2
    assert "neither a spec file nor a tier (tiers: smoke" in capsys.readouterr().err
    assert main(["experiment", "run", str(tmp_path / "gone.yaml"), "--db",
                 str(tmp_path / "r.db")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_run_unit_is_deterministic_and_plain(tmp_path):
    spec, path = load_spec(_write(tmp_path, TINY))
    unit = expand(spec, path)[0].to_data()
    first, second = run_unit(unit), run_unit(unit)
    assert first["error"] == "" and first["plan"]["status"] == "ok"
    # the target alone on the board (1 box), the baseline's straight line: a success
    assert (unit["scene"], unit["planner"]) == ("bookshelf_n01_s2015", "baseline")
    assert first["outcome"]["kind"] == "success"
    assert first["outcome"] == second["outcome"] and first["plan"] == second["plan"]
    assert "wall_time" not in first["outcome"] and "timings" not in first["plan"]
    assert first["timings"]["plan"] > 0 and first["timings"]["eval"] > 0
    assert abs(first["alpha"] - (-1.0 + 2.0 / 14 * 4.5)) < 1e-12  # approach_angles' index 4


def test_run_unit_records_an_exception_as_planner_failure(tmp_path):
    spec, path = load_spec(_write(tmp_path, TINY))
    unit = expand(spec, path)[0].to_data()
    unit["angle"] = 40  # no such approach angle: IndexError inside the worker
    result = run_unit(unit)
    assert result["outcome"]["kind"] == "planner_failure"
    assert "IndexError" in result["error"] and result["plan"] is None


def crash_or_echo(unit: dict) -> dict:
    """Test work function (run in spawned workers): the unit named CRASH_SCENE kills its
    worker process (after appending a line to its ``attempts`` file, if it has one); any
    other unit returns a result naming itself."""
    if unit["scene"] == CRASH_SCENE:
        if unit.get("attempts"):
            with open(unit["attempts"], "a") as f:
                f.write("attempt\n")
        os._exit(3)
    result = failure_result("echo", "")
    result["outcome"]["kind"], result["alpha"] = "success", float(unit["angle"])
    return result


def test_dead_worker_is_recorded_and_the_run_goes_on():
    units = [{"scene": f"s{i}", "angle": i} for i in range(5)]
    units.insert(2, {"scene": CRASH_SCENE, "angle": 99})
    got = []
    run_local(units, lambda unit, result: got.append((unit, result)), workers=2,
              work=crash_or_echo)
    assert sorted(u["scene"] for u, _ in got) == sorted(u["scene"] for u in units)
    for unit, result in got:
        if unit["scene"] == CRASH_SCENE:
            assert result["outcome"]["kind"] == "planner_failure"
            assert result["error"] == DEAD_WORKER_REASON
        else:
            assert result["outcome"]["kind"] == "success" and result["error"] == ""


def test_run_experiment_resumes_and_retries_failed(tmp_path):
    spec, path = load_spec(_write(tmp_path, TINY))
    db = tmp_path / "r.db"
    with Store(db) as store:  # a failed row from an earlier run
        unit = expand(spec, path)[1].to_data()
        store.put(unit, failure_result("worker died", "boom"))
    summary = run_experiment(spec, path, db, workers=1, progress=False)
    assert summary["ran"] == 1 and summary["skipped"] == 1  # the failed row counts as done
    text = format_summary(summary)
    assert "1 units run, 1 already in the store (of 2)" in text and "baseline: " in text
    summary = run_experiment(spec, path, db, workers=1, progress=False, retry_failed=True)
    assert summary["ran"] == 1 and summary["skipped"] == 1
    with Store(db) as store:
        rows = store.rows()
    assert len(rows) == 2 and all(r["error"] == "" for r in rows)
    again = run_experiment(spec, path, db, workers=1, progress=False, retry_failed=True)
    assert again["ran"] == 0 and again["skipped"] == 2
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT COUNT(*) FROM runs WHERE finished IS NOT NULL"
                           ).fetchone()[0] == 3


@pytest.mark.slow
def test_ray_gives_the_same_rows_as_the_local_pool_on_smoke(tmp_path):
    import ray  # noqa: F401 - the dev extra installs it; CI must run this test

    spec, path = load_spec("smoke")
    local = run_experiment(spec, path, tmp_path / "local.db", "local", 2, progress=False)
    ray_run = run_experiment(spec, path, tmp_path / "ray.db", "ray", 2, progress=False)
    assert local["ran"] == ray_run["ran"] == len(expand(spec, path))

    def table(db):
        with Store(db) as store:
            return {(r["scene"], r["planner"], r["angle"], r["config_hash"]):
                    (r["kind"], r["alpha"], r["outcome"], r["plan"], r["error"])
                    for r in store.rows()}

    a, b = table(tmp_path / "local.db"), table(tmp_path / "ray.db")
    assert a.keys() == b.keys()
    for key in a:
        assert a[key] == b[key], key


def test_split_wall_times_keeps_plans_deterministic():
    details = {"height": 0.05, "stages": {"pre": {"seconds": 1.2, "cost_history": [3.0],
                                                  "timings": {"forward": 0.7}}}}
    taken = split_wall_times(details)
    assert details == {"height": 0.05, "stages": {"pre": {"cost_history": [3.0]}}}
    assert taken == {"stages": {"pre": {"seconds": 1.2, "timings": {"forward": 0.7}}}}


def test_a_budget_record_keeps_only_what_does_not_vary_with_the_clock():
    details = {"budget": Deadline(300.0).record()}
    split_wall_times(details)
    assert details == {"budget": {"budget": 300.0, "spent": False, "cut": []}}


@pytest.mark.slow
def test_ray_retries_a_dead_worker_then_records_it(tmp_path):
    import sys

    from ray import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers cannot import tests
    attempts = tmp_path / "attempts.txt"
    units = [{"scene": f"s{i}", "angle": i} for i in range(3)]
    units.append({"scene": CRASH_SCENE, "angle": 99, "attempts": str(attempts)})
    got = {}
    run_ray(units, lambda unit, result: got.setdefault(unit["scene"], result), workers=2,
            max_retries=2, work=crash_or_echo)
    assert sorted(got) == sorted(u["scene"] for u in units)
    assert attempts.read_text().count("attempt") == 3  # the first try and 2 retries
    assert got[CRASH_SCENE]["outcome"]["kind"] == "planner_failure"
    assert "ray:" in got[CRASH_SCENE]["outcome"]["reason"]
    assert all(got[f"s{i}"]["outcome"]["kind"] == "success" for i in range(3))
