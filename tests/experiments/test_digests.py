"""experiments.digests and ``drake-clutter experiment digests``: the plans of two code versions
held against each other."""

import json

import numpy as np
import pytest

from drake_clutter.cli import main
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.digests import (
    compare_digests,
    digest,
    initializations,
    read_digests,
)
from drake_clutter.trajectory import Candidate, Trajectory


def _candidate(q0: float, seconds: float) -> Candidate:
    q = np.full((3, 8), q0)
    return Candidate(0.1, "ok", trajectory=Trajectory(np.linspace(0, 1, 3), q),
                     planner="push", timings={"total": seconds},
                     details={"search": {"seconds": seconds, "judged": 4}})


def _record(planner="push", q="a", details="b", seconds=1.0, angle=0):
    return {"tier": "smoke", "scene": "s", "angle": angle, "planner": planner, "q": q,
            "details": details, "seconds": seconds}


def test_a_digest_reads_the_plan_and_its_record_not_its_wall_times():
    same = digest(_candidate(0.2, 1.0))
    assert digest(_candidate(0.2, 7.5)) == same  # only the seconds differ
    moved = digest(_candidate(0.3, 1.0))
    assert moved[0] != same[0]
    other = _candidate(0.2, 1.0)
    other.details["search"]["judged"] = 5
    assert digest(other)[1] != same[1] and digest(other)[0] == same[0]


def test_compare_lists_the_plans_that_differ_and_the_seconds_ratio():
    old = [_record(), _record("baseline", seconds=2.0)]
    differ, text = compare_digests(old, [_record(seconds=3.0), _record("baseline", seconds=2.0)])
    assert differ == [] and "2 candidates, 0 with another plan" in text
    assert "smoke      push: old      1.0 s, new      3.0 s, x3.000" in text
    differ, text = compare_digests(old, [_record(q="c"), _record("baseline", seconds=2.0)])
    assert differ == [("smoke", "s", 0, "push")] and "differs: smoke s 0 push" in text
    with pytest.raises(InputError, match="different initializations"):
        compare_digests(old, [_record(angle=1), _record("baseline")])


def test_the_command_compares_two_files(tmp_path, capsys):
    paths = []
    for name, q in (("old", "a"), ("new", "z")):
        paths.append(tmp_path / f"{name}.jsonl")
        paths[-1].write_text(json.dumps(_record(q=q)) + "\n")
    assert main(["experiment", "digests", "--compare", str(paths[0]), str(paths[0])]) == 0
    assert main(["experiment", "digests", "--compare", *map(str, paths)]) == 1
    assert "1 with another plan or record" in capsys.readouterr().out


def test_a_file_that_is_not_digests_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"tier": "smoke"}\n')
    with pytest.raises(InputError, match="scene: missing"):
        read_digests(str(bad))
    bad.write_text("not json\n")
    assert main(["experiment", "digests", "--compare", str(bad), str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.jsonl: digests: not a digests file" in err and len(err.splitlines()) == 1


def test_the_fixed_bench_initializations_and_a_tier_are_listed():
    bench = list(initializations("bench"))
    assert len(bench) == 8 and {b[4] for b in bench} == {("baseline", "push", "physics")}
    smoke = list(initializations("smoke"))
    assert smoke and all(s[0] == "smoke" and s[4] == ("baseline", "push") for s in smoke)
    with pytest.raises(InputError):
        list(initializations("no_such_tier"))
