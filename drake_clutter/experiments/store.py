"""The results store of an experiment: one SQLite file (the standard library's sqlite3).

Table ``results`` holds one row per work unit, unique on (scene, planner, angle, config_hash):
the scene's kind and number of boxes, the configuration's name, the approach angle alpha
(rad), the outcome kind, the outcome and plan as JSON (deterministic: no wall times), the
timings as JSON (s), the error text ('' unless the unit's planner or evaluation raised or its
worker died), when it was written (Unix time) and, for a robust judge's outcome, its number of
replays, P(success), P(success or partial success) and expected grade class (NULL when the
unit was judged once; `robust.RobustSummary`). Table ``configurations`` maps each hash to
its name, overrides and the whole resolved configuration; ``runs`` logs each invocation.

Durability: WAL journal with ``synchronous=FULL``, and each result is inserted in its own
transaction as it arrives, by the one process that runs the executor. A run killed at any
moment (SIGKILL included) leaves every committed row intact and no partial row; SQLite's
journal rolls back an interrupted transaction on the next open. Re-running a spec skips the
keys already present (`done_keys`). A writing run claims the store (`claim`: an advisory lock
on the file, released with its process); a second run is refused. A store opened
``read_only`` is SQLite's ``mode=ro`` and must carry ``meta.schema``.

Formats: ``meta.schema`` names the store's; a store of an older schema gains the columns it
lacks when opened (its rows keep NULL there and read as before); an unknown schema stops with
a StoreError naming ``meta.schema``.

Failed rows (``error`` not empty: an exception or a dead worker) count as done unless the
run asks for ``retry_failed``; then they run again and the new result replaces the failed
row in one statement (`put`'s upsert only ever overwrites a row whose ``error`` is set).
A planner that simply finds no trajectory (IK failure etc.) is an outcome, not an error: it
has kind ``planner_failure`` with an empty ``error`` and is never retried.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import sqlite3
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from drake_clutter.common.typed_yaml import InputError
from drake_clutter.trajectory import Trajectory

SCHEMA_VERSION = "2"
# Columns each older schema lacks, added (NULL in old rows) when such a store is opened.
_MIGRATIONS = {"1": ("robust_replays INTEGER", "p_success REAL", "p_success_or_partial REAL",
                     "expected_grade REAL")}

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS configurations (
    config_hash TEXT PRIMARY KEY, name TEXT NOT NULL, overrides TEXT NOT NULL,
    config TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY, spec_name TEXT NOT NULL, spec_file TEXT NOT NULL,
    executor TEXT NOT NULL, workers INTEGER, started REAL NOT NULL, finished REAL,
    units INTEGER NOT NULL, skipped INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS results (
    id INTEGER PRIMARY KEY,
    scene TEXT NOT NULL, planner TEXT NOT NULL, angle INTEGER NOT NULL,
    config_hash TEXT NOT NULL, config_name TEXT NOT NULL,
    env TEXT NOT NULL, num_objects INTEGER NOT NULL, alpha REAL,
    kind TEXT NOT NULL, outcome TEXT NOT NULL, plan TEXT, timings TEXT NOT NULL,
    error TEXT NOT NULL DEFAULT '', created REAL NOT NULL,
    robust_replays INTEGER, p_success REAL, p_success_or_partial REAL, expected_grade REAL,
    UNIQUE (scene, planner, angle, config_hash));
"""

_COLUMNS = ("scene", "planner", "angle", "config_hash", "config_name", "env", "num_objects",
            "alpha", "kind", "outcome", "plan", "timings", "error", "created", "robust_replays",
            "p_success", "p_success_or_partial", "expected_grade")


class StoreError(InputError):
    """A store file that cannot be opened or is not an experiment store."""


class Store:
    """An open results store (see the module docstring). Use as a context manager."""

    def __init__(self, path: str | Path, create: bool = True, read_only: bool = False):
        """Opens the store at ``path``: created where missing (``create``), or an existing
        one; ``read_only``: an existing store opened for reading (SQLite's ``mode=ro``), which
        must carry the store's ``meta.schema`` row: any other file is refused with a
        StoreError and left as it was (a store of an older schema is opened to be migrated)."""
        self.path = Path(path)
        if (read_only or not create) and not self.path.is_file():
            raise StoreError(self.path, "", "no such store file")
        if create and not self.path.resolve().parent.is_dir():
            raise StoreError(self.path, "", "its directory does not exist")
        if read_only and self._open_read_only():
            return
        try:
            self.db = sqlite3.connect(self.path, isolation_level=None, timeout=30.0)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=FULL")
            self._init_schema()
        except sqlite3.DatabaseError as exc:
            raise StoreError(self.path, "", f"not a usable experiment store: {exc}") from None

    def _open_read_only(self) -> bool:
        """Opens the file for reading if it is a store of this schema (True); False for a store
        of an older schema (it is then opened to be migrated); a StoreError for anything else."""
        uri = f"{self.path.resolve().as_uri()}?mode=ro"
        db = sqlite3.connect(uri, uri=True, isolation_level=None, timeout=30.0)
        try:
            row = db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
        except sqlite3.DatabaseError:  # not SQLite, or SQLite without the store's tables
            row = None
        if row is None:
            db.close()
            raise StoreError(self.path, "", "not an experiment store (no meta.schema)")
        if row[0] == SCHEMA_VERSION:
            self.db = db
            return True
        db.close()
        if row[0] not in _MIGRATIONS:
            raise StoreError(self.path, "meta.schema",
                             f"schema {row[0]}, this version reads {SCHEMA_VERSION} "
                             f"(and {', '.join(_MIGRATIONS)})")
        return False

    def _init_schema(self) -> None:
        with self.transaction():
            for statement in _SCHEMA.split(";"):
                if statement.strip():
                    self.db.execute(statement)
            row = self.db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
            if row is None:
                self.db.execute("INSERT INTO meta VALUES ('schema', ?)", (SCHEMA_VERSION,))
            elif row[0] in _MIGRATIONS:
                for column in _MIGRATIONS[row[0]]:
                    self.db.execute(f"ALTER TABLE results ADD COLUMN {column}")
                self.db.execute("UPDATE meta SET value = ? WHERE key = 'schema'",
                                (SCHEMA_VERSION,))
            elif row[0] != SCHEMA_VERSION:
                raise StoreError(self.path, "meta.schema",
                                 f"schema {row[0]}, this version reads {SCHEMA_VERSION} "
                                 f"(and {', '.join(_MIGRATIONS)})")

    def transaction(self):
        """A context manager: BEGIN IMMEDIATE ... COMMIT (ROLLBACK on an exception)."""
        return _Transaction(self.db)

    def claim(self) -> None:
        """Claims the store for one writing run (an advisory lock on the file, held until
        `close` or the process ends, a kill included); a StoreError when another run holds
        it. SQLite's own locks, which this does not touch, keep each row whole; this keeps two
        runs from planning the same units."""
        handle = open(self.path, "rb")  # noqa: SIM115 - held until close
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            raise StoreError(self.path, "", "another run is writing to this store: wait for "
                             "it, or give this run another --db") from None
        self._claim = handle

    def close(self) -> None:
        """Closes the connection (and releases the run's claim)."""
        self.db.close()
        claim = getattr(self, "_claim", None)
        if claim is not None:
            claim.close()
            self._claim = None

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ writing

    def add_configuration(self, config_hash: str, name: str, overrides, config: dict) -> None:
        """Records a configuration (its first name is kept if the hash is known)."""
        with self.transaction():
            self.db.execute("INSERT OR IGNORE INTO configurations VALUES (?, ?, ?, ?)",
                            (config_hash, name, json.dumps(list(overrides)),
                             json.dumps(config, sort_keys=True)))

    def start_run(self, spec_name: str, spec_file: str, executor: str, workers: int | None,
                  units: int, skipped: int) -> int:
        """Logs an invocation; returns its id (for `finish_run`)."""
        with self.transaction():
            cursor = self.db.execute(
                "INSERT INTO runs (spec_name, spec_file, executor, workers, started, units, "
                "skipped) VALUES (?, ?, ?, ?, ?, ?, ?)",
                (spec_name, spec_file, executor, workers, time.time(), units, skipped))
        return int(cursor.lastrowid)

    def finish_run(self, run_id: int) -> None:
        """Marks a logged invocation as finished."""
        with self.transaction():
            self.db.execute("UPDATE runs SET finished = ? WHERE id = ?", (time.time(), run_id))

    def put(self, unit: dict, result: dict) -> bool:
        """Commits one unit's result (`specs.run_unit`'s dict) in its own transaction.

        Inserts the row; if the key exists, overwrites it only when the stored row failed
        (``error`` set). Returns True when a row was written.
        """
        robust = result["outcome"].get("robust") or {}
        row = (unit["scene"], unit["planner"], int(unit["angle"]), unit["config_hash"],
               unit["config_name"], unit["kind"], int(unit["num_objects"]), result["alpha"],
               result["outcome"]["kind"], json.dumps(result["outcome"], sort_keys=True),
               None if result["plan"] is None else json.dumps(result["plan"], sort_keys=True),
               json.dumps(result["timings"], sort_keys=True), result["error"], time.time(),
               len(robust["kinds"]) if robust else None, robust.get("p_success"),
               robust.get("p_success_or_partial"), robust.get("expected_grade"))
        updates = ", ".join(f"{c} = excluded.{c}" for c in _COLUMNS[4:])
        with self.transaction():
            cursor = self.db.execute(
                f"INSERT INTO results ({', '.join(_COLUMNS)}) VALUES "
                f"({', '.join('?' * len(_COLUMNS))}) "
                f"ON CONFLICT (scene, planner, angle, config_hash) DO UPDATE SET {updates} "
                f"WHERE results.error != ''", row)
        return cursor.rowcount > 0

    # ------------------------------------------------------------------ reading

    def done_keys(self, retry_failed: bool = False) -> set[tuple[str, str, int, str]]:
        """Keys (scene, planner, angle, config_hash) already stored; with ``retry_failed``
        only those without an error."""
        where = " WHERE error = ''" if retry_failed else ""
        return {tuple(r) for r in self.db.execute(
            f"SELECT scene, planner, angle, config_hash FROM results{where}")}

    def rows(self) -> list[dict]:
        """Every result row as a dict (outcome, plan and timings parsed), in insertion order."""
        cursor = self.db.execute(f"SELECT {', '.join(_COLUMNS)} FROM results ORDER BY id")
        out = []
        for values in cursor:
            row = dict(zip(_COLUMNS, values, strict=True))
            for name in ("outcome", "plan", "timings"):
                row[name] = None if row[name] is None else json.loads(row[name])
            out.append(row)
        return out

    def configurations(self) -> dict[str, dict]:
        """config_hash -> {name, overrides, config}."""
        return {h: {"name": n, "overrides": json.loads(o), "config": json.loads(c)}
                for h, n, o, c in self.db.execute("SELECT * FROM configurations")}

    def count(self) -> int:
        """Number of result rows."""
        return int(self.db.execute("SELECT COUNT(*) FROM results").fetchone()[0])

    def integrity(self) -> str:
        """SQLite's ``PRAGMA integrity_check`` answer ('ok' for a sound file)."""
        return str(self.db.execute("PRAGMA integrity_check").fetchone()[0])


class _Transaction:
    def __init__(self, db: sqlite3.Connection):
        self.db = db

    def __enter__(self):
        self.db.execute("BEGIN IMMEDIATE")
        return self.db

    def __exit__(self, exc_type, exc, tb) -> None:
        self.db.execute("COMMIT" if exc_type is None else "ROLLBACK")


def stored_plans(dbs: Sequence[str], configurations: Sequence[str] = ()
                 ) -> Iterator[tuple[str, dict, Trajectory, str]]:
    """(store, row, trajectory, digest) for every row of the stores ``dbs`` that holds a
    trajectory (only the rows of ``configurations`` when given), store by store in insertion
    order; the digest is the SHA-1 of the knots (T + 1, 8): two rows with one digest hold the
    same plan (the same baseline stored under two configurations, say)."""
    for db in dbs:
        with Store(db, read_only=True) as store:
            rows = store.rows()
        for row in rows:
            data = (row["plan"] or {}).get("trajectory")
            if not data or (configurations and row["config_name"] not in configurations):
                continue
            trajectory = Trajectory.from_data(data)
            digest = hashlib.sha1(np.ascontiguousarray(trajectory.q).tobytes()).hexdigest()
            yield db, row, trajectory, digest
