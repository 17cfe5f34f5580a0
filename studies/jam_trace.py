#!/usr/bin/env python3
"""Why the judge in phi reads a kinematic failure on a path: which box jams, where along the
path, held by what; and what the judge in Bullet read on the same plan.

    python studies/jam_trace.py --db STORE.db [--env fridge] [--levels 12 16] [--limit 10]
        [--draws 12] [--seed 0] [--out FILE.jsonl] [--set FIELD=VALUE]

For every baseline row of the store in the environment and clutter levels asked (the first
``--limit`` initializations with a plan), the baseline's straight path and ``--draws`` members
of the push family drawn about it as the search draws them (`push.aim.draw`, seeded by
``[seed, initialization]``; the feasible ones kept) are rolled out in phi's nominal member as
the judge in phi rolls them out (its pruned world, `phi_judge.judged_rollouts`' phi), knot by
knot with each box's jam measure (`phi.jam`). For each path: the first knot whose jam reaches
``phi_judge.jam_depth`` (as a fraction of the path's duration), the box it jams (the target
or an obstacle) and what holds that box at that knot: its contacts carrying a force with the
static geometry (a board, read from a contact normal within 45 degrees of vertical, or a wall)
and with other boxes. Also, per initialization, the boxes the straight path's capsule arm
enters with the boxes at rest (`push.aim.obstructions`: depth, and where along the path) and
the boxes the pre-grasp pose itself enters, and the judge's stored reason for the baseline's
plan and, where the store holds it, the push planner's.

Printed: one block per initialization and a summary: how many paths jam, on which box (the
target, a box the pre-grasp pose enters, another), held by what, and how late.

With ``--grasp-only`` nothing is rolled out: for every baseline row of the store with a plan
(all environments, levels and planners), how deep the capsule arm at the plan's last knot
(the pre-grasp pose) enters its deepest other box at rest, against the stored robust
P(success), per environment, level and planner: whether a grasp is reached where the arm at
the grasp has no room among the boxes as they stand.

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import Store
from drake_clutter.phi.dynamics import initial_state, make_spec
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.mujoco_phi import STATIC, contact_magnitudes
from drake_clutter.phi.pruning import prune
from drake_clutter.phi.state import scene_box_states
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.members import member_world
from drake_clutter.planners.push.aim import draw, obstructions
from drake_clutter.planners.push.family import feasible, member_path
from drake_clutter.planners.tool_path import approach_frame

BOARD_NORMAL_Z = 0.7  # |n_z| above this reads a board (floor or ceiling), else a wall (ours)


def rows_of(db: str, env: str, levels: list[int], limit: int) -> list[tuple[dict, dict]]:
    """(baseline row, push row or None) of the first ``limit`` initializations with a plan."""
    with Store(db, read_only=True) as store:
        rows = store.rows()
    push = {(r["scene"], r["angle"]): r for r in rows if r["planner"] == "push"}
    chosen = [r for r in rows if r["planner"] == "baseline" and r["env"] == env
              and r["num_objects"] in levels and (r["plan"] or {}).get("trajectory")]
    chosen.sort(key=lambda r: (r["num_objects"], r["scene"], r["angle"]))
    return [(r, push.get((r["scene"], r["angle"]))) for r in chosen[:limit]]


def holders(phi, box: int) -> tuple[list[str], list[str], float | None]:
    """What touches kept box ``box`` (layout index) in phi's data now, for each contact
    carrying a force: 'board', 'wall' or a box name; the arm's parts on it; and the z
    component of the arm's mean push direction into it (W; -1 straight down; None: no arm
    contact)."""
    m, d = phi.model, phi.data
    n = d.ncon
    if n == 0:
        return [], [], None
    magnitude = contact_magnitudes(m, d)
    geoms = d.contact.geom[:n]
    nodes = phi._nodes[geoms]
    names = list(phi.layout.box_names)
    frozen = [name for name, _ in phi.spec.frozen]
    out, parts, pushes = set(), set(), []
    for k in np.flatnonzero(magnitude >= 1e-3):
        a, b = nodes[k]
        if box + 1 not in (a, b) or a == b:
            continue
        other = b if a == box + 1 else a
        normal = d.contact.frame[k, :3]  # from geom 1 into geom 2
        if other == STATIC:
            out.add("board" if abs(normal[2]) > BOARD_NORMAL_Z else "wall")
        elif other == 0:
            parts.add(m.geom(int(geoms[k, 0] if a == 0 else geoms[k, 1])).name)
            pushes.append(normal if a == 0 else -normal)
        elif other > 0:
            out.add(names[other - 1])
        else:
            out.add(f"{frozen[-other - 1]} (frozen)")
    push = np.mean(pushes, axis=0) if pushes else None
    down = None if push is None else float(push[2] / max(np.linalg.norm(push), 1e-12))
    return sorted(out), sorted(parts), down


def trace_paths(scene, config, paths: dict[str, np.ndarray], knot_time: float) -> dict:
    """Each path's first jam in phi's nominal member (module docstring)."""
    world, cfg = member_world(scene, config, 0)
    dyn = replace(cfg.dynamics, engine=cfg.phi_judge.engine)
    states = scene_box_states(world)
    first, *others = paths.values()
    kept = prune(world, first, states, dyn, cfg.world, "capsules", tuple(others)).kept
    spec = make_spec(world, [b.name for b in world.boxes if b.name in kept], states,
                     knot_time, dyn, cfg.world, "capsules")
    phi = build_phi(spec)
    x0 = phi.settle(initial_state(spec.layout, first[0], states))
    depth, hold = cfg.phi_judge.jam_depth, cfg.phi_judge.hold_knots
    out = {}
    for name, q in paths.items():
        x = x0.copy()
        x[:len(q[0])] = q[0]
        knots = [*q[1:], *([q[-1]] * hold)]
        found = {"jam": None, "worst": 0.0}
        for k, u in enumerate(knots, start=1):
            x, jam = phi.step_jam(x, u)
            if not np.all(np.isfinite(jam)):
                found["failed"] = k / (len(q) - 1)
                break
            found["worst"] = max(found["worst"], float(jam.max(initial=0.0)))
            if jam.size and jam.max() >= depth:
                b = int(np.argmax(jam))
                held, parts, push_z = holders(phi, b)
                found["jam"] = {"box": phi.layout.box_names[b], "at": k / (len(q) - 1),
                                "depth": float(jam[b]), "held_by": held, "arm": parts,
                                "push_z": push_z}
                break
        out[name] = found
    return out


def initialization(task) -> dict:
    """The trace of one initialization (module docstring)."""
    base, push, config, draws, seed = task
    scene = stored_scene(base["scene"], config)
    context = PlanningContext(scene, config)
    geometry = context.arm()
    times = np.asarray(base["plan"]["trajectory"]["times"], float)
    q = np.asarray(base["plan"]["trajectory"]["q"], float)
    frame = approach_frame(geometry, q)
    found = obstructions(geometry, q, frame, scene.target)
    at_grasp: dict[str, float] = {}
    for c in geometry.contacts(q[-1], max_distance=0.0, obstacles="boxes"):
        if c.obstacle != scene.target and c.distance < 0.0:
            at_grasp[c.obstacle] = max(at_grasp.get(c.obstacle, 0.0), -c.distance)
    paths = {"straight": q}
    rng = np.random.default_rng([seed, base["angle"], int(base["num_objects"])])
    for i in range(draws):
        member = draw(rng, frame, found, config.push_search)
        try:
            path, error = member_path(geometry, q, member)
        except (RuntimeError, ValueError):
            continue
        if feasible(path, error, times, context.clearance, config):
            paths[f"m{i}"] = path
    traced = trace_paths(scene, config, paths, float(times[1] - times[0]))
    judged = {"baseline": base["outcome"].get("reason", ""),
              "push": None if push is None else push["outcome"].get("reason", "")}
    return {"scene": base["scene"], "angle": base["angle"], "target": scene.target,
            "obstructions": [{"box": o.box, "depth": o.depth, "along": o.along,
                              "lateral": o.lateral} for o in found],
            "at_grasp": at_grasp, "paths": traced, "judge": judged,
            "kinds": {"baseline": base["kind"], "push": None if push is None else push["kind"]},
            "push_chosen": None if push is None else
            ((push["plan"] or {}).get("details") or {}).get("chosen")}


def grasp_room(db: str, config, deep: float) -> str:
    """The ``--grasp-only`` table (module docstring); ``deep`` (m) splits the plans."""
    with Store(db, read_only=True) as store:
        rows = store.rows()
    groups: dict = {}
    scenes: dict = {}
    for r in rows:
        if not (r["plan"] or {}).get("trajectory") or r["p_success"] is None:
            continue
        if r["scene"] not in scenes:
            scene = stored_scene(r["scene"], config)
            scenes[r["scene"]] = (scene, PlanningContext(scene, config).arm())
        scene, geometry = scenes[r["scene"]]
        q = np.asarray(r["plan"]["trajectory"]["q"], float)
        depth = max((-c.distance for c in geometry.contacts(q[-1], max_distance=0.0,
                                                            obstacles="boxes")
                     if c.obstacle != scene.target), default=0.0)
        key = (r["env"], r["num_objects"], r["planner"], depth > deep)
        groups.setdefault(key, []).append((depth, r["p_success"]))
    lines = [f"| env | boxes | planner | its last knot enters a box by > {deep * 1e3:.0f} mm | "
             "plans | median depth (mm) | robust P(success) |", "|---|---:|---|---|---:|---:|---:|"]
    for (env, n, planner, entered), items in sorted(groups.items()):
        depths, p = zip(*items, strict=True)
        lines.append(f"| {env} | {n} | {planner} | {'yes' if entered else 'no'} | {len(items)} "
                     f"| {np.median(depths) * 1e3:.0f} | {np.mean(p):.3f} |")
    return "\n".join(lines)


def summary(results: list[dict]) -> str:
    """Counts over every traced path (module docstring)."""
    where, held, pushed, late, n = Counter(), Counter(), Counter(), [], 0
    for r in results:
        for found in r["paths"].values():
            n += 1
            jam = found["jam"]
            if jam is None:
                where["no jam" if "failed" not in found else "phi failed"] += 1
                continue
            kind = ("target" if jam["box"] == r["target"]
                    else "a box the pre-grasp pose enters" if jam["box"] in r["at_grasp"]
                    else "a box the straight path meets" if jam["box"] in
                    {o["box"] for o in r["obstructions"]} else "another box")
            where[kind] += 1
            held[", ".join(sorted({h if h in ("board", "wall") else "box"
                                   for h in jam["held_by"]})) or "nothing"] += 1
            z = jam["push_z"]
            pushed["no arm contact at the knot's end" if z is None else "down (n_z < -0.7)"
                   if z < -BOARD_NORMAL_Z else "up (n_z > 0.7)" if z > BOARD_NORMAL_Z
                   else "sideways"] += 1
            late.append(jam["at"])
    lines = [f"{n} paths of {len(results)} initializations"]
    lines += [f"  jammed box: {k}: {v}" for k, v in where.most_common()]
    lines += [f"  held by: {k}: {v}" for k, v in held.most_common()]
    lines += [f"  the arm pushes it: {k}: {v}" for k, v in pushed.most_common()]
    if late:
        lines.append(f"  first jam at fraction of the path: median {np.median(late):.2f}, "
                     f"quartiles {np.quantile(late, 0.25):.2f}-{np.quantile(late, 0.75):.2f}")
    return "\n".join(lines)


def block(r: dict) -> str:
    """One initialization's lines."""
    obs = ", ".join(f"{o['box']} {o['depth'] * 1e3:.0f} mm" for o in r["obstructions"])
    lines = [f"{r['scene']} angle {r['angle']} (target {r['target']}); straight path meets: "
             f"{obs or 'nothing'}; pre-grasp pose enters: "
             f"{', '.join(f'{b} {d * 1e3:.0f} mm' for b, d in r['at_grasp'].items()) or '-'}",
             f"  judge: baseline {r['kinds']['baseline']} ({r['judge']['baseline']}); push, "
             f"path {r.get('push_chosen')}: {r['kinds']['push']} ({r['judge']['push']})"]
    for name, found in r["paths"].items():
        jam = found["jam"]
        text = ("no jam" if jam is None and "failed" not in found else "phi failed"
                if jam is None else f"{jam['box']} at {jam['at']:.2f}, "
                f"{jam['depth'] * 1e3:.1f} mm, held by {', '.join(jam['held_by']) or '-'}; "
                f"pushed by {', '.join(jam['arm']) or '-'} (n_z "
                f"{'-' if jam['push_z'] is None else format(jam['push_z'], '+.2f')})")
        lines.append(f"  {name:>8}: {text}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--env", default="fridge")
    parser.add_argument("--levels", type=int, nargs="+", default=[12, 16])
    parser.add_argument("--limit", type=int, default=10)
    parser.add_argument("--draws", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="JSON-lines file of the traces")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--grasp-only", action="store_true")
    parser.add_argument("--deep", type=float, default=0.005, help="m (--grasp-only)")
    args = parser.parse_args(argv)
    try:
        config = load_config(None, args.overrides)
        if args.grasp_only:
            print(grasp_room(args.db, config, args.deep))
            return 0
        rows = rows_of(args.db, args.env, args.levels, args.limit)
    except InputError as err:
        print(err, file=sys.stderr)
        return 2
    results = []
    for base, push in rows:
        r = initialization((base, push, config, args.draws, args.seed))
        print(block(r), flush=True)
        results.append(r)
        if args.out:
            with open(args.out, "a", encoding="utf-8") as f:
                f.write(json.dumps(r) + "\n")
    print(summary(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
