"""The plans a code version makes, as digests: one JSON line per planner and initialization,
to hold two versions' plans against each other (a refactor must not change them).

    drake-clutter experiment digests smoke behaviours bench --out new.jsonl
    drake-clutter experiment digests --compare old.jsonl new.jsonl

A tier name (``smoke``, ``behaviours``, ...) plans every initialization of the tier (its
scenes, angles and configurations) with the baseline and the push planner; ``bench`` plans
bookshelf scenes of 10 and 25 boxes (seeds 0, 1; angles 3, 10) with the baseline, the push and
the physics planner. Each line: the SHA-1 (12 digits) of the knots and of the candidate's record
with its wall times removed (`specs.split_wall_times`), and the planning seconds.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import defaultdict
from collections.abc import Iterator, Sequence

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.specs import build_scene, expand, load_spec, split_wall_times
from drake_clutter.planners.registry import get_planner
from drake_clutter.trajectory import Candidate

BENCH = "bench"  # the name of the fixed bookshelf initializations (module docstring)


def digest(candidate: Candidate) -> tuple[str, str]:
    """SHA-1 (12 digits) of the candidate's knots and of its record without wall times."""
    q = (np.zeros(0) if candidate.trajectory is None
         else np.ascontiguousarray(candidate.trajectory.q))
    data = candidate.to_data()
    data.pop("timings", None)
    split_wall_times(data["details"])
    record = json.dumps(data, sort_keys=True, default=str).encode()
    return hashlib.sha1(q.tobytes()).hexdigest()[:12], hashlib.sha1(record).hexdigest()[:12]


def initializations(which: str) -> Iterator[tuple]:
    """(tier, scene source, angle index, overrides, planners) of a tier or of ``bench``; an
    unknown tier raises InputError."""
    if which == BENCH:
        for n in (10, 25):
            for seed in (0, 1):
                for angle in (3, 10):
                    yield (which, ("generated", "bookshelf", n, seed), angle,
                           ["dynamics.workers=0"], ("baseline", "push", "physics"))
        return
    seen = set()
    for unit in expand(load_spec(which)[0]):
        key = (str(unit.source), unit.angle, unit.overrides)
        if key not in seen:
            seen.add(key)
            yield which, unit.source, unit.angle, list(unit.overrides), ("baseline", "push")


def plan_digests(tiers: Sequence[str]) -> Iterator[dict]:
    """One record per planner and initialization of ``tiers`` (tier, scene, angle, planner,
    the two digests, planning seconds), planned one at a time in this process."""
    for which in tiers:
        for tier, source, angle, overrides, planners in initializations(which):
            config = load_config(None, overrides)
            scene = build_scene(source, config)
            planned: dict[str, list] = {}
            for name in planners:
                planner = get_planner(name)
                tic = time.perf_counter()
                (candidate,) = planner.plan(scene, config, [angle],
                                            planned.get(planner.starts_from))
                seconds = time.perf_counter() - tic
                planned[name] = [candidate]
                q, record = digest(candidate)
                yield {"tier": tier, "scene": scene.name, "angle": angle, "planner": name,
                       "q": q, "details": record, "seconds": round(seconds, 3)}


def read_digests(path: str) -> list[dict]:
    """The records of a digests file; an unreadable one raises InputError naming it."""
    try:
        with open(path, encoding="utf-8") as handle:
            rows = [json.loads(line) for line in handle if line.strip()]
        for row in rows:
            for field in ("tier", "scene", "angle", "planner", "q", "details", "seconds"):
                if field not in row:
                    raise InputError(path, field, "missing from a line")
        return rows
    except (OSError, ValueError) as exc:
        raise InputError(path, "digests", f"not a digests file: {exc}") from None


def compare_digests(old: list[dict], new: list[dict]) -> tuple[list[tuple], str]:
    """(the initializations whose plan or record differ, a text report with the seconds per
    tier and planner, new over old); files of different initializations raise InputError."""
    keys = [(r["tier"], r["scene"], r["angle"], r["planner"]) for r in old]
    if keys != [(r["tier"], r["scene"], r["angle"], r["planner"]) for r in new]:
        raise InputError("<command line>", "--compare",
                         "the two files hold different initializations")
    differ = [k for k, a, b in zip(keys, old, new, strict=True)
              if (a["q"], a["details"]) != (b["q"], b["details"])]
    lines = [f"{len(keys)} candidates, {len(differ)} with another plan or record"]
    lines += ["  differs: " + " ".join(map(str, k)) for k in differ]
    seconds = defaultdict(lambda: [0.0, 0.0])
    for k, a, b in zip(keys, old, new, strict=True):
        seconds[(k[0], k[3])][0] += a["seconds"]
        seconds[(k[0], k[3])][1] += b["seconds"]
    for (tier, planner), (a, b) in sorted(seconds.items()):
        lines.append(f"{tier:>12} {planner:>9}: old {a:8.1f} s, new {b:8.1f} s, "
                     f"x{b / max(a, 1e-9):.3f}")
    return differ, "\n".join(lines) + "\n"
