"""Re-judging a store's plans: the same plans, a changed judge.

No planner reads the ``evaluation`` settings, so a stored plan is the plan its unit would make
again under any judge. `rejudge` replays every stored plan of a store under its stored
configuration with ``evaluation.*`` overrides (the robust judge, a finer Bullet step) and writes
each as a row of another store, under the changed configuration's hash and the same
configuration name, with the source row's planning timings and its own evaluation time.
Rows without a trajectory (the planner found none) are carried over with the new hash as they
are; so are failed rows (an exception, a dead worker), which keep their error. Like an
experiment run, it is resumable: a row already in the destination is skipped.

A raised force limit is cheap to re-judge (`unaffected`): a replay stops at its first kinematic
failure and never otherwise reads ``max_static_force``, so a replay that ended in another class
never crossed the lower limit and cannot cross a higher one. When the judge's settings differ
from the stored ones only by a raised ``max_static_force``, a row none of whose replays (the
nominal and the robust ones) is a kinematic failure keeps its stored outcome and evaluation
time without a replay; only the rows with a kinematic failure are replayed.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Sequence

from drake_clutter.common.config import (
    Config,
    ConfigError,
    config_from_data,
    config_to_data,
    upgrade_stored,
)
from drake_clutter.common.typed_yaml import from_data

JUDGE_SECTIONS = ("evaluation", "report", "viz")  # settings no planner reads
RAISED_LIMITS = ("max_static_force",)  # judge limits whose crossing only ends a replay early


def check_overrides(overrides: Sequence[str], file: str = "<command line>") -> None:
    """Raises ConfigError for an override that is not ``section.field=value`` of a section no
    planner reads (JUDGE_SECTIONS): any other would need the plans made again."""
    for item in overrides:
        key, sep, _ = item.partition("=")
        section = key.strip().split(".")[0]
        if not sep or section not in JUDGE_SECTIONS:
            raise ConfigError(file, key.strip() or item, "re-judging changes only the judge's "
                              f"settings ({', '.join(JUDGE_SECTIONS)}): the plans are stored")


def changed_config(data: dict, overrides: Sequence[str]) -> Config:
    """A stored configuration (`config_to_data`'s data; fields added since it was stored take
    their defaults, fields moved since are read under their new names: `upgrade_stored`) with
    ``overrides`` applied."""
    return config_from_data(upgrade_stored(data), overrides)


def unaffected(row: dict, stored: dict, changed: dict) -> bool:
    """True when re-judging ``row`` under the ``evaluation`` section ``changed`` (data) must give
    back its outcome under ``stored``: the two sections differ only by raised `RAISED_LIMITS`
    and none of the row's replays (nominal and robust) is a kinematic failure."""
    differ = {key for key in set(stored) | set(changed) if stored.get(key) != changed.get(key)}
    if not differ or not differ <= set(RAISED_LIMITS):
        return False
    if any(changed[key] < stored[key] for key in differ):
        return False
    outcome = row["outcome"] or {}
    kinds = [outcome.get("kind")] + list((outcome.get("robust") or {}).get("kinds", []))
    return "kinematic_failure" not in kinds


def rejudge_unit(task: dict) -> dict:
    """Replays one stored row's plan under ``task["config"]`` (data); the result as
    `specs.run_unit` returns it, or the row's own result when it has no trajectory."""
    from drake_clutter.evaluation.judge import evaluate_candidates
    from drake_clutter.evaluation.outcome import Outcome
    from drake_clutter.experiments.specs import DEAD_WORKER, stored_scene
    from drake_clutter.trajectory import Candidate

    row = task["row"]
    carried = {"alpha": row["alpha"], "plan": row["plan"], "outcome": row["outcome"],
               "timings": row["timings"], "error": row["error"]}
    if task.get("carry") or row["error"] or not (row["plan"] or {}).get("trajectory"):
        return carried
    try:
        config = from_data(Config, task["config"], file="<stored configuration>")
        scene = stored_scene(row["scene"], config)
        tic = time.perf_counter()
        outcome = evaluate_candidates(scene, [Candidate.from_data(row["plan"])],
                                      config.evaluation)[0]
        seconds = time.perf_counter() - tic
    except Exception as exc:  # a failure to replay is a recorded row, not a crash
        data = Outcome(DEAD_WORKER, f"exception: {exc!r}").to_data()
        data.pop("wall_time", None)
        return {**carried, "outcome": data,
                "error": "".join(traceback.format_exception(exc))[-4000:]}
    data = outcome.to_data()
    data.pop("wall_time", None)
    timings = {**(row["timings"] or {}), "eval": seconds, "eval_wall": outcome.wall_time}
    return {**carried, "outcome": data, "timings": timings}


def rejudge(source: str, destination: str, overrides: Sequence[str], workers: int = 1,
            progress: bool = True, current_judge: bool = False,
            carry_unaffected: bool = True) -> dict:
    """Re-judges every row of the store ``source`` into ``destination`` (module docstring);
    with ``current_judge`` the stored ``evaluation`` section is first replaced by today's
    defaults (the judge's defaults changed since the store was written); with
    ``carry_unaffected`` (the default) the rows `unaffected` by the change keep their outcome
    unreplayed, otherwise every plan is replayed. Returns the summary `executors.format_summary`
    prints, with ``carried``: the rows kept unreplayed."""
    from drake_clutter.experiments.executors import StoreWriter, run_local
    from drake_clutter.experiments.specs import config_hash
    from drake_clutter.experiments.store import Store, StoreError

    check_overrides(overrides)
    started = time.perf_counter()
    with Store(source, read_only=True) as store:
        rows, configurations = store.rows(), store.configurations()
    tasks, hashes = [], {}
    for row in rows:
        if row["config_hash"] not in hashes:
            stored = configurations.get(row["config_hash"])
            if stored is None:
                raise StoreError(source, "configurations", f"no configuration stored for "
                                 f"hash {row['config_hash']} (row of {row['scene']})")
            data = dict(stored["config"])
            if current_judge:
                data["evaluation"] = config_to_data(Config())["evaluation"]
            config = changed_config(data, overrides)
            judged = upgrade_stored(dict(stored["config"])).get("evaluation", {})
            hashes[row["config_hash"]] = (config_hash(config), config_to_data(config), stored,
                                          judged)
        new_hash, config_data, _, judged = hashes[row["config_hash"]]
        carry = carry_unaffected and unaffected(row, judged, config_data["evaluation"])
        unit = {"scene": row["scene"], "planner": row["planner"], "angle": row["angle"],
                "config_hash": new_hash, "config_name": row["config_name"], "kind": row["env"],
                "num_objects": row["num_objects"]}
        tasks.append({**unit, "row": row, "config": config_data, "carry": carry})
    with Store(destination) as out:
        out.claim()
        for new_hash, config_data, stored, _ in hashes.values():
            out.add_configuration(new_hash, stored["name"],
                                  list(stored["overrides"]) + list(overrides), config_data)
        done = out.done_keys()
        todo = [t for t in tasks if (t["scene"], t["planner"], t["angle"], t["config_hash"])
                not in done]
        writer = StoreWriter(out, len(todo), "rejudge", progress)
        try:
            run_local(todo, writer, workers, work=rejudge_unit)
        finally:
            writer.close()
    summary = writer.summary(f"rejudge of {source}", len(tasks), len(tasks) - len(todo),
                             time.perf_counter() - started, "local")
    return {**summary, "carried": sum(bool(t["carry"]) for t in todo)}
