"""experiments.compare and ``drake-clutter stores compare``: planners of two stores compared on
the initializations both have."""

import pytest

from drake_clutter.cli import main
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.compare import compare_table, load_stores, shared
from drake_clutter.experiments.store import Store


def _store(path, config, kinds: dict[str, dict[tuple[str, int], str]]):
    """A store of nominal rows: planner -> (scene, angle) -> outcome kind."""
    with Store(path) as store:
        for planner, units in kinds.items():
            for (scene, angle), kind in units.items():
                unit = {"scene": scene, "planner": planner, "angle": angle, "config_hash": config,
                        "config_name": config, "kind": "bookshelf", "num_objects": 5}
                store.put(unit, {"alpha": 0.0, "outcome": {"kind": kind},
                                 "plan": {"status": "ok"}, "timings": {}, "error": ""})


@pytest.fixture
def two_stores(tmp_path):
    a, b = ("bookshelf_n05_s1", 0), ("bookshelf_n05_s1", 1)
    c = ("bookshelf_n05_s2", 0)  # only in the first store: not read
    _store(tmp_path / "one.db", "defaults", {
        "baseline": {a: "failure_to_grasp", b: "success", c: "success"},
        "push": {a: "success", b: "success", c: "failure_to_grasp"}})
    _store(tmp_path / "two.db", "stages", {
        "baseline": {a: "failure_to_grasp", b: "success"},
        "physics": {a: "kinematic_failure", b: "kinematic_failure"}})
    return [str(tmp_path / "one.db"), str(tmp_path / "two.db")]


def test_rows_of_two_stores_are_compared_on_their_shared_initializations(two_stores):
    named = shared(load_stores(two_stores))
    assert {len(rows) for rows in named.values()} == {2}
    out = compare_table(named, "defaults/baseline")
    assert out.startswith("2 initializations, 1 scenes")
    # push: +1 at a, 0 at b; physics: 0 at a (both fail), -1 at b.
    assert "| defaults/push | 100.0 % | 100.0 % | 1.000 | +0.500 [" in out
    assert "| 1 / 1 / 0 |" in out
    assert "| stages/physics | 0.0 % | 0.0 % | 0.000 | -0.500 [" in out
    assert ("| stages/baseline | 100.0 % | 100.0 % | 0.500 | +0.000 [+0.000, +0.000] "
            "| 0 / 2 / 0 |") in out


def test_the_command_prints_the_table(two_stores, capsys):
    assert main(["stores", "compare", *two_stores, "--against", "defaults/baseline"]) == 0
    assert "| defaults/push | 100.0 % |" in capsys.readouterr().out


def test_the_same_row_name_in_two_stores_is_refused(tmp_path):
    for name in ("one.db", "two.db"):
        _store(tmp_path / name, "defaults", {"baseline": {("bookshelf_n05_s1", 0): "success"}})
    with pytest.raises(InputError, match="also in"):
        load_stores([str(tmp_path / "one.db"), str(tmp_path / "two.db")])


@pytest.mark.parametrize("args, says", [
    (["--against", "defaults/nothing"], "--against: no row defaults/nothing"),
    (["--against", "defaults/push", "missing.db"], "no such store file")])
def test_bad_input_is_one_line_and_exit_2(two_stores, tmp_path, capsys, args, says):
    stores = [*two_stores, *(str(tmp_path / a) for a in args[2:])]
    assert main(["stores", "compare", *stores, *args[:2]]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1


def test_stores_that_share_no_initialization_are_refused(tmp_path):
    _store(tmp_path / "one.db", "defaults", {"baseline": {("bookshelf_n05_s1", 0): "success"}})
    _store(tmp_path / "two.db", "other", {"baseline": {("bookshelf_n05_s2", 0): "success"}})
    named = shared(load_stores([str(tmp_path / "one.db"), str(tmp_path / "two.db")]))
    with pytest.raises(InputError, match="no initialization is shared"):
        compare_table(named, "defaults/baseline")
