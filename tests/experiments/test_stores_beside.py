"""benchmarks/stores_beside.py: planners of two stores compared on the initializations both have."""

import importlib.util
from pathlib import Path

import pytest

from drake_clutter.experiments.store import Store

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "stores_beside.py"


def _script():
    spec = importlib.util.spec_from_file_location("stores_beside", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _store(path, config, kinds: dict[str, dict[tuple[str, int], str]]):
    """A store of nominal rows: planner -> (scene, angle) -> outcome kind."""
    with Store(path) as store:
        for planner, units in kinds.items():
            for (scene, angle), kind in units.items():
                unit = {"scene": scene, "planner": planner, "angle": angle, "config_hash": config,
                        "config_name": config, "kind": "bookshelf", "num_objects": 5}
                store.put(unit, {"alpha": 0.0, "outcome": {"kind": kind},
                                 "plan": {"status": "ok"}, "timings": {}, "error": ""})


def test_rows_of_two_stores_are_compared_on_their_shared_initializations(tmp_path, capsys):
    a, b = ("bookshelf_n05_s1", 0), ("bookshelf_n05_s1", 1)
    c = ("bookshelf_n05_s2", 0)  # only in the first store: not read
    _store(tmp_path / "one.db", "defaults", {
        "baseline": {a: "failure_to_grasp", b: "success", c: "success"},
        "push": {a: "success", b: "success", c: "failure_to_grasp"}})
    _store(tmp_path / "two.db", "stages", {
        "baseline": {a: "failure_to_grasp", b: "success"},
        "physics": {a: "kinematic_failure", b: "kinematic_failure"}})
    module = _script()
    named = module.shared(module.load([str(tmp_path / "one.db"), str(tmp_path / "two.db")]))
    assert {len(rows) for rows in named.values()} == {2}
    assert module.main([str(tmp_path / "one.db"), str(tmp_path / "two.db"),
                        "--against", "defaults/baseline"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("2 initializations, 1 scenes")
    # push: +1 at a, 0 at b; physics: 0 at a (both fail), -1 at b.
    assert "| defaults/push | 100.0 % | 100.0 % | 1.000 | +0.500 [" in out
    assert "| 1 / 1 / 0 |" in out
    assert "| stages/physics | 0.0 % | 0.0 % | 0.000 | -0.500 [" in out
    assert ("| stages/baseline | 100.0 % | 100.0 % | 0.500 | +0.000 [+0.000, +0.000] "
            "| 0 / 2 / 0 |") in out


def test_the_same_row_name_in_two_stores_is_refused(tmp_path):
    for name in ("one.db", "two.db"):
        _store(tmp_path / name, "defaults", {"baseline": {("bookshelf_n05_s1", 0): "success"}})
    with pytest.raises(SystemExit, match="also in"):
        _script().load([str(tmp_path / "one.db"), str(tmp_path / "two.db")])
