#!/usr/bin/env python3
"""Benchmark of the judge in phi (beyond the paper): paths judged per second, against a
reference revision of the code measured in the same run, and the verdicts compared member by
member.

    python benchmarks/bench_phi_judge.py                       # 8 probe inits, K = 4
    python benchmarks/bench_phi_judge.py --reference HEAD~3 --inits bookshelf:20:6016:4
    python benchmarks/bench_phi_judge.py --variant "phi_judge.sleep=false" \
        --variant "phi_judge.threads=2"                         # settings side by side
    python benchmarks/bench_phi_judge.py --variant "dynamics.workers=2"  # members in 2 processes

The paths (fixed, seeded): per initialization (kind:level:seed:angle of the probe tier's
generator), the baseline's straight paths at the push planner's grasp heights and the search's
first-round draws (`aim.draw`, seeded like the search) that are feasible. They are built once
with this checkout's code and saved; then each side judges all of them in the same K members
of phi (``phi_judge.engine``) the way the search does (``judge_paths(..., complete=False)``),
in one process per side, one side at a time, this checkout (once per ``--variant``, each
with its own overrides) and the reference (a git revision, checked out into a temporary
worktree) alternating ``--repeats`` times. Printed per variant: per initialization and in
total the paths, each side's seconds (the best of the repeats) and the ratio; then the member
readings whose class differs (``--show`` of them), with both sides' findings (the reason).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

DEFAULT_INITS = ("bookshelf:5:3015:4", "bookshelf:10:4015:4", "bookshelf:15:5016:6",
                 "bookshelf:20:6016:9", "fridge:4:10015:6", "fridge:8:12016:7",
                 "fridge:12:14015:4", "fridge:16:16017:9")
DEFAULT_REFERENCE = "685b895"  # the judge in phi knot by knot at 2 ms, pruned (2026-11-29)
ROOT = Path(__file__).resolve().parents[1]


def judge_config(config, members: int):
    """``config`` with the judge in phi's members set to ``members``, in the configuration
    layout of the code that runs (a reference from before the judge had its own section judged
    in ``dynamics.engine`` with ``ensemble.members``, the search setting both)."""
    if hasattr(config, "phi_judge"):
        return replace(config, phi_judge=replace(config.phi_judge, members=members))
    return replace(config, dynamics=replace(config.dynamics, engine=config.push_search.engine),
                   ensemble=replace(config.ensemble, members=members))


def search_paths(item: str, config):
    """(scene, {name: knots (T + 1, 8)}, times (s)) of one initialization: the straight
    starts and the search's first-round draws that are feasible."""
    from drake_clutter.planners.context import PlanningContext
    from drake_clutter.planners.push.aim import draw
    from drake_clutter.planners.push.search import Search
    from drake_clutter.planners.registry import get_planner
    from drake_clutter.planners.starts import height_candidates, start_key
    from drake_clutter.scene.generators import generate_scene

    kind, level, seed, angle = item.split(":")
    scene = generate_scene(kind, int(level), int(seed), config.generator)
    (candidate,) = get_planner("baseline").plan(scene, config, [int(angle)])
    if candidate.trajectory is None:
        return scene, {}, None
    context = PlanningContext(scene, config)
    found = height_candidates(context, candidate)
    starts = {start_key(*key): c.trajectory.q for key, c in found.items()}
    search = Search(context, starts, candidate.trajectory.times)
    rng = np.random.default_rng([config.push_search.seed, int(angle), 0])
    names = list(starts)
    for i in range(config.push_search.samples):
        start = names[i % len(starts)]
        frame, met = search.frame(start)
        search.add(f"{start}/r0m{i}", start, draw(rng, frame, met, config.push_search))
    return scene, {n: s.q for n, s in search.samples.items()}, candidate.trajectory.times


def judge_saved(paths_file: str, out_file: str, members: int, settings: list[str]) -> None:
    """Judges the saved paths with the importable ``drake_clutter`` (``settings``: --set
    overrides) and writes, per initialization, its seconds and every path's findings per
    member (JSON)."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.context import PlanningContext
    from drake_clutter.planners.phi_judge import judge_paths

    config = judge_config(load_config(None, ["dynamics.workers=0", *settings]), members)
    with open(paths_file, "rb") as f:
        saved = pickle.load(f)
    pool = worker_pool(config)
    out = {}
    try:
        for item, (scene, paths, times) in saved.items():
            geometry = PlanningContext(scene, config).arm()
            tic = time.perf_counter()
            verdicts = judge_paths(scene, paths, times, config, geometry, pool=pool,
                                   complete=False)
            out[item] = {"seconds": time.perf_counter() - tic,
                         "verdicts": {n: v.to_data() for n, v in verdicts.items()}}
    finally:
        if pool is not None:
            pool.close()
    Path(out_file).write_text(json.dumps(out))


def worker_pool(config):
    """A started pool of ``dynamics.workers`` processes that roll the members out (as the
    planner's loop does), ready before the clock starts; None for 0 (members in turn here)."""
    workers = getattr(config.dynamics, "workers", 0)
    if workers <= 0:
        return None
    from drake_clutter.phi.workers import WorkerPool

    pool = WorkerPool(workers)
    pool.start()
    pool.run(_imported, ["drake_clutter.planners.phi_judge"] * (2 * workers))
    return pool


def _imported(module: str) -> bool:
    """Imports ``module`` (in a worker, before the clock starts)."""
    importlib.import_module(module)
    return True


def run_side(source: Path, paths_file: str, members: int, settings: list[str]) -> dict:
    """`judge_saved` in a fresh process with ``source``'s ``drake_clutter`` first on the path."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out_file = f.name
    env = {**os.environ, "PYTHONPATH": str(source)}
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--judge-only", paths_file,
                    "--out", out_file, "--members", str(members), "--set", *settings],
                   env=env, check=True,
                   cwd=tempfile.gettempdir())
    return json.loads(Path(out_file).read_text())


def differences(new: dict, old: dict) -> list[str]:
    """One line per member reading whose class differs, with both sides' findings."""
    lines = []
    for item, side in new.items():
        for name, v in side["verdicts"].items():
            w = old[item]["verdicts"][name]
            for k, (a, b) in enumerate(zip(v["kinds"], w["kinds"], strict=True)):
                if a != b:
                    lines.append(f"{item} {name} member {k}: {b} -> {a}; reference "
                                 f"{w['reasons'][k]!r} {w['findings'][k]}, now "
                                 f"{v['reasons'][k]!r} {v['findings'][k]}")
    return lines


def jams_differing(new: dict, old: dict) -> int:
    """Member findings whose jam measure (m) is not the same number on both sides."""
    return sum(a["jam"] != b["jam"]
               for item, side in new.items() for name, v in side["verdicts"].items()
               for a, b in zip(v["findings"], old[item]["verdicts"][name]["findings"],
                               strict=True))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inits", nargs="+", default=list(DEFAULT_INITS),
                        help="kind:level:seed:angle (default: %(default)s)")
    parser.add_argument("--members", type=int, default=4, help="K (default: %(default)s)")
    parser.add_argument("--reference", default=DEFAULT_REFERENCE,
                        help="git revision of the reference (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=1, help="alternations (default: 1)")
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE",
                        help="overrides for this checkout's side only, e.g. "
                        "phi_judge.threads=2")
    parser.add_argument("--variant", action="append", default=[], metavar="'FIELD=VALUE ...'",
                        help="a side of this checkout with these overrides (repeatable: each "
                        "variant judged in the same run against the same reference; "
                        "replaces --set)")
    parser.add_argument("--show", type=int, default=20,
                        help="differing readings printed per variant (default: %(default)s)")
    parser.add_argument("--judge-only", metavar="PATHS", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.judge_only:
        judge_saved(args.judge_only, args.out, args.members, args.set)
        return
    from drake_clutter.common.config import load_config

    config = load_config(None, ["dynamics.workers=0"])
    saved = {}
    for item in args.inits:
        scene, paths, times = search_paths(item, config)
        if paths:
            saved[item] = (scene, paths, times)
    with tempfile.TemporaryDirectory() as tmp:
        paths_file = os.path.join(tmp, "paths.pkl")
        with open(paths_file, "wb") as f:
            pickle.dump(saved, f)
        reference = Path(tmp) / "reference"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q",
                        str(reference), args.reference], check=True)
        variants = [v.split() for v in args.variant] or [args.set]
        try:
            runs = {"reference": [], **{i: [] for i in range(len(variants))}}
            for _ in range(args.repeats):
                runs["reference"].append(run_side(reference, paths_file, args.members, []))
                for i, settings in enumerate(variants):
                    runs[i].append(run_side(ROOT, paths_file, args.members, settings))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(reference)], check=False)
    report(saved, runs, args, variants)


def report(saved: dict, runs: dict, args, variants: list[list[str]]) -> None:
    """Prints, per variant of this checkout, the table and the differing readings."""
    best = {side: {item: min(r[item]["seconds"] for r in rs) for item in saved}
            for side, rs in runs.items()}
    n = sum(len(paths) for _, paths, _ in saved.values())
    readings = n * args.members
    r_total = sum(best["reference"].values())
    print(f"K = {args.members}, reference {args.reference}, best of {args.repeats}; "
          f"reference {r_total:.1f} s, {n / r_total:.2f} paths per second")
    for i, settings in enumerate(variants):
        print(f"\nnow with {' '.join(settings) or 'the defaults'}")
        print(f"{'initialization':>22} {'paths':>5} {'reference s':>11} {'now s':>7} "
              f"{'ratio':>6}")
        for item, (_, paths, _) in saved.items():
            r, s = best["reference"][item], best[i][item]
            print(f"{item:>22} {len(paths):5d} {r:11.1f} {s:7.1f} {r / s:6.2f}")
        s = sum(best[i].values())
        print(f"{'total':>22} {n:5d} {r_total:11.1f} {s:7.1f} {r_total / s:6.2f}")
        print(f"paths judged per second: reference {n / r_total:.2f}, now {n / s:.2f}")
        lines = differences(runs[i][0], runs["reference"][0])
        print(f"member readings that differ: {len(lines)} of {readings}; jam measures that "
              f"differ: {jams_differing(runs[i][0], runs['reference'][0])} of {readings}")
        for line in lines[:args.show]:
            print("  " + line)


if __name__ == "__main__":
    main()
