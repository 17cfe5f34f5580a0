"""The SQLite results store: unique rows, upserts of failed rows only, resume after SIGKILL."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drake_clutter.cli import main
from drake_clutter.experiments.specs import failure_result
from drake_clutter.experiments.store import Store, StoreError
from drake_clutter.testing.processes import alive, children

REPO = Path(__file__).resolve().parents[2]


def _unit(scene="s", angle=0, planner="baseline", config_hash="h"):
    return {"scene": scene, "planner": planner, "angle": angle, "config_hash": config_hash,
            "config_name": "default", "kind": "bookshelf", "num_objects": 3}


def _ok(kind="success", alpha=0.1):
    return {"alpha": alpha, "outcome": {"kind": kind, "reason": "r"},
            "plan": {"status": "ok", "trajectory": {"q": [[0.0, 1.0]]}},
            "timings": {"plan": 1.5, "eval": 0.5}, "error": ""}


def test_put_and_read_back(tmp_path):
    with Store(tmp_path / "r.db") as store:
        assert store.put(_unit(angle=0), _ok())
        assert store.put(_unit(angle=1), _ok("failure_to_grasp"))
        rows = store.rows()
        assert [r["angle"] for r in rows] == [0, 1]
        assert rows[0]["outcome"] == {"kind": "success", "reason": "r"}
        assert rows[0]["plan"]["trajectory"]["q"] == [[0.0, 1.0]]
        assert rows[1]["kind"] == "failure_to_grasp" and rows[1]["env"] == "bookshelf"
        assert store.done_keys() == {("s", "baseline", 0, "h"), ("s", "baseline", 1, "h")}
        assert store.integrity() == "ok"


def test_a_finished_row_is_never_overwritten_a_failed_one_is(tmp_path):
    with Store(tmp_path / "r.db") as store:
        assert store.put(_unit(), _ok("success"))
        assert not store.put(_unit(), _ok("kinematic_failure"))  # same key: ignored
        assert store.rows()[0]["kind"] == "success" and store.count() == 1
        store.put(_unit(angle=1), failure_result("worker died", "traceback ..."))
        assert ("s", "baseline", 1, "h") in store.done_keys()
        assert ("s", "baseline", 1, "h") not in store.done_keys(retry_failed=True)
        assert store.put(_unit(angle=1), _ok("partial_success"))  # replaces the failure
        rows = store.rows()
        assert store.count() == 2 and rows[1]["kind"] == "partial_success"
        assert rows[1]["error"] == ""


def test_unique_key_holds_in_sql(tmp_path):
    with Store(tmp_path / "r.db") as store:
        store.put(_unit(), _ok())
    with sqlite3.connect(tmp_path / "r.db") as con, pytest.raises(sqlite3.IntegrityError):
        con.execute("INSERT INTO results (scene, planner, angle, config_hash, config_name, env, "
                    "num_objects, kind, outcome, timings, created) VALUES "
                    "('s', 'baseline', 0, 'h', 'x', 'bookshelf', 1, 'success', '{}', '{}', 0)")


def test_bad_store_files(tmp_path, capsys):
    with pytest.raises(StoreError, match="no such store file"):
        Store(tmp_path / "missing.db", create=False)
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"this is not a database at all" * 100)
    with pytest.raises(StoreError, match="not a usable experiment store"):
        Store(junk)
    assert main(["report", str(tmp_path / "missing.db"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "missing.db" in err


SPEC = """
name: kill_test
planners: [baseline]
generated:
  - {kind: fridge, levels: [1], seeds: [7]}
angles: [2, 4, 6, 7, 9, 11]
overrides: [dynamics.workers=0]
"""


def _count(db: Path) -> int:
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0) as con:
            return con.execute("SELECT COUNT(*) FROM results").fetchone()[0]
    except sqlite3.OperationalError:  # the schema is not there yet
        return 0


def _rows(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as con:
        return con.execute("SELECT scene, planner, angle, config_hash, kind, outcome, plan "
                           "FROM results ORDER BY scene, angle").fetchall()


def _foreground_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


# How a run is stopped: the signal, sent to the runner alone or to its whole process group (a
# terminal's Ctrl-C, the machine killing the job), and the exit status the runner then has.
STOPS = {"sigkill of the job": (signal.SIGKILL, True, -signal.SIGKILL),
         "sigkill of the runner alone": (signal.SIGKILL, False, -signal.SIGKILL),
         "sigterm of the runner": (signal.SIGTERM, False, 143),
         "ctrl-c in a terminal": (signal.SIGINT, True, 130)}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("stop", list(STOPS))
def test_a_stopped_run_ends_its_workers_and_resumes_losing_and_doubling_nothing(tmp_path,
                                                                                 stop):
    signum, group, status = STOPS[stop]
    spec, db = tmp_path / "spec.yaml", tmp_path / "run.db"
    spec.write_text(SPEC, encoding="utf-8")
    command = [sys.executable, "-m", "drake_clutter.cli", "experiment", "run", str(spec),
               "--db", str(db), "--workers", "2", "--no-progress"]
    # Its own session, so that a signal to the group reaches the runner and its workers
    # together and none reaches pytest; Ctrl-C as in a foreground terminal, even where the
    # suite itself runs in the background (there a shell starts it with SIGINT ignored, and
    # the runner would inherit that).
    proc = subprocess.Popen(command, cwd=REPO, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            preexec_fn=_foreground_sigint)
    try:
        deadline = time.monotonic() + 120
        while _count(db) < 1 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before it could be stopped"
        workers = children(proc.pid)
        assert _count(db) >= 1 and len(workers) >= 2
        (os.killpg if group else os.kill)(proc.pid, signum)
        assert proc.wait(timeout=30) == status
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    deadline = time.monotonic() + 15
    while any(alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(w) for w in workers), "a worker outlived its runner"
    before = _rows(db)
    assert 1 <= len(before) < 6
    done = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{6 - len(before)} units run, {len(before)} already in the store" in done.stdout
    after = _rows(db)
    assert len(after) == 6 and len({r[:4] for r in after}) == 6
    assert set(before) <= set(after)  # committed rows are untouched
    with sqlite3.connect(db) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_robust_outcomes_fill_their_columns(tmp_path):
    robust = {"seed": 0, "kinds": ["success", "failure_to_grasp", "success", "success"],
              "grades": [[0, 0], [2, 0], [0, 0], [0, 1]], "p_success": 0.75,
              "p_success_or_partial": 0.75, "expected_grade": 0.5}
    result = _ok()
    result["outcome"] = {**result["outcome"], "robust": robust}
    with Store(tmp_path / "r.db") as store:
        store.put(_unit(angle=0), result)
        store.put(_unit(angle=1), _ok())
        first, second = store.rows()
    assert (first["robust_replays"], first["p_success"], first["expected_grade"]) == (4, 0.75, 0.5)
    assert first["outcome"]["robust"] == robust
    assert second["robust_replays"] is None and second["p_success"] is None


def test_a_store_of_the_first_schema_gains_the_columns_and_reads_as_before(tmp_path):
    path = tmp_path / "old.db"
    with Store(path) as store:
        store.put(_unit(), _ok())
    db = sqlite3.connect(path)  # make it what the first schema wrote
    for column in ("robust_replays", "p_success", "p_success_or_partial", "expected_grade"):
        db.execute(f"ALTER TABLE results DROP COLUMN {column}")
    db.execute("UPDATE meta SET value = '1' WHERE key = 'schema'")
    db.commit()
    db.close()
    with Store(path, create=False) as store:
        (row,) = store.rows()
        assert row["kind"] == "success" and row["p_success"] is None
        assert store.put(_unit(angle=1), _ok("partial_success"))
    assert sqlite3.connect(path).execute("SELECT value FROM meta").fetchone() == ("2",)


def test_a_store_of_an_unknown_schema_stops_with_its_field(tmp_path):
    path = tmp_path / "future.db"
    with Store(path) as store:
        store.put(_unit(), _ok())
    db = sqlite3.connect(path)
    db.execute("UPDATE meta SET value = '9' WHERE key = 'schema'")
    db.commit()
    db.close()
    with pytest.raises(StoreError) as err:
        Store(path, create=False)
    assert err.value.field == "meta.schema" and "schema 9" in err.value.reason


def test_stored_plans_reads_each_trajectory_with_a_digest_of_its_knots(tmp_path):
    import numpy as np

    from drake_clutter.experiments.store import stored_plans
    from drake_clutter.trajectory import Trajectory

    def plan(q0: float) -> dict:
        q = np.full((3, 8), q0)
        return {"status": "ok", "trajectory": Trajectory(np.arange(3.0), q).to_data()}

    with Store(tmp_path / "a.db") as store:
        store.put(_unit(angle=0), {**_ok(), "plan": plan(0.1)})
        store.put(_unit(angle=1, planner="physics"), {**_ok(), "plan": plan(0.1)})
        store.put(_unit(angle=2), {**_ok(), "plan": plan(0.2)})
        store.put(_unit(angle=3), {**_ok("planner_failure"), "plan": {"status": "ik_failed"}})
    with Store(tmp_path / "b.db") as store:
        unit = {**_unit(angle=0), "config_name": "other"}
        store.put(unit, {**_ok(), "plan": plan(0.1)})
    dbs = [str(tmp_path / "a.db"), str(tmp_path / "b.db")]
    found = list(stored_plans(dbs))
    assert [(db[-4:], row["angle"]) for db, row, _, _ in found] == [
        ("a.db", 0), ("a.db", 1), ("a.db", 2), ("b.db", 0)]  # the row without a plan: none
    digests = [digest for *_, digest in found]
    assert digests[0] == digests[1] == digests[3] != digests[2]
    assert np.array_equal(found[2][2].q, np.full((3, 8), 0.2))
    assert [row["angle"] for _, row, _, _ in stored_plans(dbs, ["other"])] == [0]


def _not_stores(tmp_path: Path) -> dict[str, Path]:
    """An empty file, someone else's SQLite file and a text file."""
    empty = tmp_path / "empty.db"
    empty.write_bytes(b"")
    foreign = tmp_path / "users.db"
    with sqlite3.connect(foreign) as con:
        con.execute("CREATE TABLE users (name TEXT)")
        con.execute("INSERT INTO users VALUES ('ada')")
    con.close()
    text = tmp_path / "notes.txt"
    text.write_text("not a database\n" * 50)
    return {"empty": empty, "foreign": foreign, "text": text}


@pytest.mark.parametrize("command", ["report", "rejudge"])
def test_reading_a_file_that_is_not_a_store_refuses_it_and_leaves_it_as_it_was(
        tmp_path, capsys, command):
    for name, path in _not_stores(tmp_path).items():
        before = path.read_bytes()
        args = (["report", str(path), "--out", str(tmp_path / "out")] if command == "report"
                else ["experiment", "rejudge", str(path), "--db", str(tmp_path / "new.db"),
                      "--set", "evaluation.max_static_force=75"])
        assert main(args) == 2, name
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not an experiment store" in err[0] and path.name in err[0]
        assert path.read_bytes() == before, name
        assert not Path(f"{path}-wal").exists() and not Path(f"{path}-shm").exists()
        assert not (tmp_path / "new.db").exists()


def test_a_store_opened_for_reading_cannot_be_written(tmp_path):
    with Store(tmp_path / "r.db") as store:
        store.put(_unit(), _ok())
    with Store(tmp_path / "r.db", read_only=True) as store:
        assert store.count() == 1
        with pytest.raises(sqlite3.OperationalError, match="readonly"):
            store.put(_unit(angle=1), _ok())


def test_report_out_under_a_file_is_one_line_naming_out(tmp_path, capsys):
    with Store(tmp_path / "r.db") as store:
        store.put(_unit(), _ok())
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    for out in (plain, plain / "report"):
        assert main(["report", str(tmp_path / "r.db"), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--out" in err[0] and "plain.txt" in err[0]


def test_a_second_run_on_a_store_being_written_is_refused_in_one_line(tmp_path, capsys):
    from drake_clutter.testing.specs import TINY_SPEC

    spec = tmp_path / "tiny.yaml"
    spec.write_text(TINY_SPEC)
    db = tmp_path / "r.db"
    with Store(db) as first:
        first.put(_unit(), _ok())
        first.claim()  # a run writing to it
        assert main(["experiment", "run", str(spec), "--db", str(db), "--no-progress"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "another run is writing to this store" in err[0]
        assert first.count() == 1  # nothing planned, nothing written
    with Store(db) as again:  # the claim ends with its holder
        again.claim()
