#!/usr/bin/env python3
"""How the push planner's answer grows with the paths its search judges: a curve, not a point.

    python studies/search_curve.py --db STORE.db [--configuration margin] [--stride 2]
        [--rounds 5] [--population 20] [--elite 4] [--jobs 2] [--cache FILE.jsonl]
        [--set FIELD=VALUE ...]

The initializations are those of a stored push run (``--db``, its ``--configuration``) whose
planner searched (no clear straight start), every ``--stride``-th. On each:

* the baseline's path and today's search (``push_search`` as configured: "perturb") are planned
  and their returned paths judged by the robust judge (``evaluation.robust_replays``, K = 8 in
  the tiers); today's path is checked against the stored one (the same knots);
* the cross-entropy search (``push_search.method=cem``, ``--rounds`` rounds of
  ``--population`` paths about ``--elite`` elite) runs once; after each round the path the
  planner would return if stopped there (the veto on held-out members, then the fallback to the
  baseline's path when nothing reads a grasp in phi) is judged by the robust judge.

Printed: per round, the mean paths judged in phi, the mean robust P(success), the paired
difference against today's search and against the baseline (bootstrap 95 % intervals over the
initializations), and how often the returned path is a bent one with robust P(success) >= 0.5.
An initialization whose angle has no baseline path (the push planner searched from a turned
angle's line) is skipped and counted.
``--cache`` keeps one JSON line per initialization, so a stopped run resumes.

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from drake_clutter.common.config import ReportConfig, load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.experiments.paired import bootstrap_interval
from drake_clutter.experiments.specs import plan_one_angle, stored_scene
from drake_clutter.experiments.store import stored_plans
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.push.planner import falls_back
from drake_clutter.planners.push.search import run_search
from drake_clutter.planners.registry import get_planner
from drake_clutter.planners.starts import height_candidates, start_key
from drake_clutter.trajectory import Trajectory

FIXED = ["dynamics.workers=0", "evaluation.robust_replays=8"]  # as the tiers run a unit


def digest(q) -> str:
    """SHA-1 of a path's knots (as the stores digest them)."""
    return hashlib.sha1(np.ascontiguousarray(np.asarray(q, float)).tobytes()).hexdigest()


def searched(db: str, configuration: str) -> list[tuple[str, int, str]]:
    """(scene, angle, stored plan digest) of the push rows of ``configuration`` that searched."""
    out = []
    for _, row, _trajectory, found in stored_plans([db], [configuration]):
        details = (row["plan"] or {}).get("details") or {}
        if row["planner"] == "push" and get_planner("push").record(details).search:
            out.append((row["scene"], int(row["angle"]), found))
    return out


def returned(name: str, q: np.ndarray, verdict: dict | None, baseline_q: np.ndarray,
             config) -> tuple[str, np.ndarray]:
    """What the push planner returns for the search's chosen path ``name`` (knots ``q``, its
    verdict summary ``verdict``): it, or the baseline's path where the planner falls back
    (`planner.falls_back`)."""
    return ("baseline", baseline_q) if falls_back(verdict, config) else (name, q)


def one(job: dict) -> dict:
    """One initialization (module docstring): the JSON-ready line."""
    config = load_config(None, [*FIXED, *job["sets"]])
    cem = load_config(None, [*FIXED, *job["sets"], "push_search.method=cem",
                             f"push_search.rounds={job['rounds']}",
                             f"push_search.population={job['population']}",
                             f"push_search.elite={job['elite']}"])
    scene = stored_scene(job["scene"], config)
    baseline = plan_one_angle(scene, config, "baseline", job["angle"])
    if baseline.trajectory is None:  # the push planner searched from turned angles' lines
        return {"scene": job["scene"], "angle": job["angle"],
                "skipped": f"no baseline path at this angle ({baseline.reason})"}
    context = PlanningContext(scene, config)
    times = baseline.trajectory.times
    starts = {start_key(*k): c.trajectory.q
              for k, c in height_candidates(context, baseline).items()}
    judged: dict[str, dict] = {}

    def judge(q) -> dict:
        key = digest(q)
        if key not in judged:
            outcome = evaluate(scene, Trajectory(times, np.asarray(q)), config.evaluation)
            judged[key] = {"p_success": outcome.robust.p_success, "kind": str(outcome.kind),
                           "expected_grade": outcome.robust.expected_grade}
        return judged[key]

    tic = time.perf_counter()
    today = run_search(context, starts, times, job["angle"])
    today_seconds = time.perf_counter() - tic
    t_name, t_q = returned(today.name, today.q, today.record["verdicts"].get(today.name),
                           baseline.trajectory.q, config)
    checkpoints, last, clock = [], {}, {"spent": 0.0, "tic": time.perf_counter()}

    def observe(round_, search, best_start):
        clock["spent"] += time.perf_counter() - clock["tic"]  # the search's own time
        pick = search.best(list(search.verdicts))
        if last.get("pick") != pick:
            chosen, _ = search.veto(pick, best_start)
            verdict = search.verdicts.get(chosen)
            last.update(pick=pick, answer=returned(
                chosen, search.samples[chosen].q,
                verdict and {"kinds": [r.kind for r in verdict.readings]},
                baseline.trajectory.q, cem))
        name, q = last["answer"]
        checkpoints.append({"round": round_, "paths": len(search.verdicts), "chosen": name,
                            "bent": "/" in name, "seconds": clock["spent"], **judge(q)})
        clock["tic"] = time.perf_counter()

    run_search(context.with_config(cem), starts, times, job["angle"], observe=observe)
    return {"scene": job["scene"], "angle": job["angle"],
            "baseline": judge(baseline.trajectory.q),
            "today": {"chosen": t_name, "paths": len(today.record["verdicts"]),
                      "seconds": today_seconds,
                      "bent": "/" in t_name, "same_as_stored": digest(t_q) == job["stored"],
                      **judge(t_q)},
            "cem": checkpoints}


def at_round(line: dict, r: int) -> dict:
    """The cross-entropy search's answer after round ``r`` (0-based) of one initialization:
    its last round's where it stopped earlier, today's where it drew nothing (its best start
    read P(success) >= ``push_search.stop_at`` in phi: both return that start)."""
    if not line["cem"]:
        return line["today"]
    return line["cem"][min(r, len(line["cem"]) - 1)]


def summary(lines: list[dict]) -> str:
    """The printed table (module docstring)."""
    report = ReportConfig()
    base = np.array([x["baseline"]["p_success"] for x in lines])
    today = np.array([x["today"]["p_success"] for x in lines])

    def row(label, paths, p, bent_good, seconds=()):
        d_today, d_base = p - today, p - base
        lo, hi = bootstrap_interval(d_today, report)
        blo, bhi = bootstrap_interval(d_base, report)
        return (f"{label:>10} {np.mean(paths):7.1f} {np.mean(p):7.3f} "
                f"{np.mean(d_today):+7.3f} [{lo:+.3f}, {hi:+.3f}] "
                f"{np.mean(d_base):+7.3f} [{blo:+.3f}, {bhi:+.3f}] {np.mean(bent_good):6.2f} "
                f"{np.mean(seconds) if len(seconds) else float('nan'):6.1f}")

    out = [f"{len(lines)} initializations that searched; same as stored (today): "
           f"{sum(x['today']['same_as_stored'] for x in lines)}",
           f"{'answer':>10} {'paths':>7} {'P succ':>7} {'- today [95 %]':>24} "
           f"{'- baseline [95 %]':>24} {'bent>=.5':>6} {'search s':>6}",
           row("baseline", [0] * len(lines), base, [False] * len(lines)),
           row("today", [x["today"]["paths"] for x in lines], today,
               [x["today"]["bent"] and x["today"]["p_success"] >= 0.5 for x in lines],
               [x["today"].get("seconds", np.nan) for x in lines])]
    for r in range(max(len(x["cem"]) for x in lines)):
        points = [at_round(x, r) for x in lines]
        out.append(row(f"cem r{r + 1}", [c["paths"] for c in points],
                       np.array([c["p_success"] for c in points]),
                       [c["bent"] and c["p_success"] >= 0.5 for c in points],
                       [c.get("seconds", np.nan) for c in points]))
    return "\n".join(out)


def main(argv=None) -> int:
    """The command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--configuration", default="margin")
    parser.add_argument("--stride", type=int, default=2)
    parser.add_argument("--offset", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--population", type=int, default=20)
    parser.add_argument("--elite", type=int, default=4)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path)
    parser.add_argument("--set", action="append", default=[], dest="sets")
    args = parser.parse_args(argv)
    try:
        load_config(None, [*FIXED, *args.sets])
        inits = searched(args.db, args.configuration)[args.offset::max(1, args.stride)]
    except (InputError, OSError) as exc:
        print(f"search_curve: {exc}", file=sys.stderr)
        return 2
    done = {}
    if args.cache and args.cache.exists():
        for text in args.cache.read_text().splitlines():
            line = json.loads(text)
            done[(line["scene"], line["angle"])] = line
    jobs = [{"scene": s, "angle": a, "stored": d, "sets": args.sets, "rounds": args.rounds,
             "population": args.population, "elite": args.elite}
            for s, a, d in inits if (s, a) not in done]
    with ProcessPoolExecutor(args.jobs) as pool:
        for future in as_completed([pool.submit(one, job) for job in jobs]):
            line = future.result()
            done[(line["scene"], line["angle"])] = line
            if "skipped" in line:
                print(f"{line['scene']} {line['angle']}: skipped, {line['skipped']}", flush=True)
            else:
                print(f"{line['scene']} {line['angle']}: baseline "
                      f"{line['baseline']['p_success']:.2f}"
                      f" today {line['today']['p_success']:.2f} cem "
                      f"{[c['p_success'] for c in line['cem']]}", flush=True)
            if args.cache:
                with args.cache.open("a") as f:
                    f.write(json.dumps(line) + "\n")
    lines = [done[(s, a)] for s, a, _ in inits if (s, a) in done]
    skipped = [x for x in lines if "skipped" in x]
    if skipped:
        print(f"{len(skipped)} initializations skipped: no baseline path at their angle")
    print(summary([x for x in lines if "skipped" not in x]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
