#!/usr/bin/env python3
"""Where the boxes that crowd the grasp could go: can pushing them make room for the pre-grasp
pose, and how far must they travel?

    python studies/grasp_room.py --db STORE.db [--env fridge] [--levels 12 16] [--limit 0]
        [--deep 0.005] [--step 0.005] [--travel 0.2] [--directions 16] [--chain 3]
        [--push-only] [--out FILE.jsonl] [--set FIELD=VALUE]
    python studies/grasp_room.py --from FILE.jsonl [FILE.jsonl ...]

For every baseline row of the store with a plan (in the environment and levels asked; the
first ``--limit`` by level, scene and angle, 0: all), the capsule arm is put at the plan's last
knot (the pre-grasp pose) and every box other than the target it enters by more than
``--deep`` (m) with the boxes at rest is to be cleared: moved, as a rigid translation on the
board, until the arm no longer enters it. For each such box, deepest first, every one of
``--directions`` horizontal directions is tried, in ``--step`` (m) increments up to
``--travel`` (m): a moved box that overlaps another box's footprint pushes that box ahead of
it along the same direction, as far as it must (a chain of at most ``--chain`` boxes); a move
that would push the target, leave a box's footprint off the board or through a wall, or need a
longer chain is blocked. The cheapest direction (least total travel of the boxes moved) is
kept, and the next box is cleared from there. With ``--push-only`` no direction with a
component back toward the robot is tried (a push from the approach side cannot pull a box
out). The initialization has room once no box other
than the target is entered by more than ``--deep``.

This is geometry only, an upper bound on what a clear-the-grasp move could achieve: it does
not ask whether the arm can reach behind a box to push it that way, nor what friction and the
boxes' tipping would do. Where it finds no room, no slide within these limits (directions,
travel, chain length, boxes cleared one at a time, deepest first) makes it.

Printed: one line per initialization and a table per environment and level: initializations,
the share with room, how many box moves it takes (a box moved twice counts twice), their
total travel (m), how many need a chain, which way the cleared boxes go in the approach frame
(deeper, sideways, back out), and the push planner's stored robust P(success) where the
pre-grasp pose is not crowded, where room can be made and where it cannot; then, pooled,
both planners' P(success) by how many boxes must move.
``--from`` prints the tables of earlier ``--out`` files without recomputing.

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import Store
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.rearrange.board import Board
from drake_clutter.planners.rearrange.board import entered as board_entered
from drake_clutter.planners.rearrange.board import world_poses as board_world_poses
from drake_clutter.planners.tool_path import approach_frame


def baseline_rows(db: str, env: str, levels: list[int], limit: int) -> list[dict]:
    """The store's baseline rows with a plan in ``env`` at ``levels``, ordered; ``limit`` 0:
    all. Each gains ``p_push``: the push planner's robust P(success) on the same
    initialization (None: the store has no such row)."""
    with Store(db, read_only=True) as store:
        rows = store.rows()
    push = {(r["scene"], r["angle"]): r["p_success"] for r in rows if r["planner"] == "push"}
    for r in rows:
        r["p_push"] = push.get((r["scene"], r["angle"]))
    chosen = [r for r in rows if r["planner"] == "baseline" and r["env"] == env
              and r["num_objects"] in levels and (r["plan"] or {}).get("trajectory")]
    chosen.sort(key=lambda r: (r["num_objects"], r["scene"], r["angle"]))
    return chosen[:limit] if limit else chosen


def entered(geometry, scene, q: np.ndarray, poses: dict) -> dict[str, float]:
    """Depth (m) by which the capsule arm at ``q`` enters each box other than the target, the
    boxes at ``poses`` (X_WB by name)."""
    return board_entered(geometry, q, poses, frozenset([scene.target]))


def world_poses(geometry, board: Board, offsets: dict) -> dict:
    """X_WB of every box: its resting pose translated by its offset."""
    return board_world_poses(geometry, offsets)


def clear_box(geometry, board: Board, q, name: str, offsets: dict, d: np.ndarray,
              args) -> dict | None:
    """The cheapest way found to move box ``name`` until the arm at ``q`` leaves it: the
    offsets after, its direction (2,) and the total travel (m); None: every direction is
    blocked within ``args.travel``. With ``args.push_only`` no direction back toward the
    robot (cosine with the approach direction ``d`` (2,) below -0.1) is tried."""
    best = None
    for angle in np.linspace(0.0, 2 * np.pi, args.directions, endpoint=False):
        u = np.array([np.cos(angle), np.sin(angle)])
        if args.push_only and u @ d < -0.1:
            continue
        for step in np.arange(args.step, args.travel + 1e-9, args.step):
            new = board.push(offsets, name, step * u)
            if new is None:
                break
            if name not in entered(geometry, board.scene, q, world_poses(geometry, board, new)):
                travel = sum(float(np.linalg.norm(new[k] - offsets.get(k, np.zeros(2))))
                             for k in new)
                if best is None or travel < best["travel"]:
                    best = {"offsets": new, "u": u, "travel": travel}
                break
    return best


def initialization(row: dict, config, args) -> dict:
    """One initialization's result (module docstring)."""
    scene = stored_scene(row["scene"], config)
    geometry = PlanningContext(scene, config).arm()
    q = np.asarray(row["plan"]["trajectory"]["q"], float)
    frame = approach_frame(geometry, q)
    board = Board(scene, args.chain)
    rest = world_poses(geometry, board, {})
    before = {k: v for k, v in entered(geometry, scene, q[-1], rest).items() if v > args.deep}
    offsets: dict = {}
    cleared, blocked = [], []
    for name in sorted(before, key=before.get, reverse=True):
        now = entered(geometry, scene, q[-1], world_poses(geometry, board, offsets))
        if now.get(name, 0.0) <= args.deep:
            continue  # an earlier move cleared it
        best = clear_box(geometry, board, q[-1], name, offsets, frame.d[:2], args)
        if best is None:
            blocked.append(name)
            continue
        moved = [k for k in best["offsets"] if
                 np.linalg.norm(best["offsets"][k] - offsets.get(k, np.zeros(2))) > 1e-6]
        offsets = best["offsets"]
        u = best["u"]
        cleared.append({"box": name, "travel": best["travel"], "moved": moved,
                        "along": float(u @ frame.d[:2]), "side": float(u @ frame.side[:2])})
    after = entered(geometry, scene, q[-1], world_poses(geometry, board, offsets))
    worst = max(after.values(), default=0.0)
    return {"scene": row["scene"], "angle": row["angle"], "env": row["env"],
            "level": row["num_objects"], "target": scene.target, "entered": before,
            "cleared": cleared, "blocked": blocked, "room": not blocked and worst <= args.deep,
            "left": worst, "kind": row["kind"], "p_baseline": row["p_success"],
            "p_push": row["p_push"]}


def with_(c: dict) -> str:
    """The other boxes a clearing move pushes ahead of its box, as text."""
    others = [k for k in c["moved"] if k != c["box"]]
    return f", with {', '.join(others)}" if others else ""


def line(r: dict) -> str:
    """One initialization's line."""
    moves = "; ".join(f"{c['box']} {c['travel'] * 1e3:.0f} mm (along {c['along']:+.2f}, side "
                      f"{c['side']:+.2f}{with_(c)})" for c in r["cleared"])
    enters = ", ".join(f"{b} {d * 1e3:.0f} mm" for b, d in r["entered"].items()) or "-"
    return (f"{r['scene']} angle {r['angle']}: enters {enters} -> "
            f"{'ROOM' if r['room'] else 'no room'}; {moves or '-'}"
            f"{'; blocked: ' + ', '.join(r['blocked']) if r['blocked'] else ''}")


def way(c: dict) -> str:
    """Which way a cleared box went in the approach frame."""
    if c["along"] > 0.7:
        return "deeper"
    if c["along"] < -0.7:
        return "back out"
    return "sideways"


def mean_p(results: list[dict]) -> str:
    """The push planner's mean robust P(success) over ``results``, as text ('-': none)."""
    p = [r["p_push"] for r in results if r.get("p_push") is not None]
    return f"{np.mean(p):.2f} ({len(p)})" if p else "-"


def table(results: list[dict]) -> str:
    """Per environment and level (module docstring)."""
    lines = ["| env | boxes | initializations | crowded (> deep) | room made | box moves "
             "(median) | travel, median (m) | needs a chain | ways (deeper/sideways/back out) "
             "| push P(success): not crowded / room made / not |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|---|"]
    groups: dict = {}
    for r in results:
        groups.setdefault((r["env"], r["level"]), []).append(r)
    for (env, level), rs in sorted(groups.items()):
        crowded = [r for r in rs if r["entered"]]
        room = [r for r in crowded if r["room"]]
        free = [r for r in rs if not r["entered"]]
        shut = [r for r in crowded if not r["room"]]
        moved = [sum(len(c["moved"]) for c in r["cleared"]) for r in room]
        travel = [sum(c["travel"] for c in r["cleared"]) for r in room]
        chain = sum(any(len(c["moved"]) > 1 for c in r["cleared"]) for r in room)
        ways = Counter(way(c) for r in room for c in r["cleared"])
        lines.append(
            f"| {env} | {level} | {len(rs)} | {len(crowded)} | {len(room)} | "
            f"{np.median(moved) if moved else '-'} | "
            f"{format(np.median(travel), '.3f') if travel else '-'} | {chain} | "
            f"{ways['deeper']}/{ways['sideways']}/{ways['back out']} | "
            f"{mean_p(free)} / {mean_p(room)} / {mean_p(shut)} |")
    return "\n".join(lines)


def by_moves(results: list[dict]) -> str:
    """Pooled over ``results``: the initializations by how many boxes must move to make room
    (0: the pre-grasp pose is not crowded; 'no room': none found), with both planners' mean
    robust P(success) and the median total travel."""
    bins: dict = {}
    for r in results:
        moved = len({b for c in r["cleared"] for b in c["moved"]})
        key = (0 if not r["entered"] else 6 if not r["room"] else min(moved, 5))
        bins.setdefault(key, []).append(r)
    lines = ["| boxes to move | initializations | baseline P(success) | push P(success) | "
             "travel, median (m) |", "|---|---:|---:|---:|---:|"]
    for key, rs in sorted(bins.items()):
        label = {0: "0 (not crowded)", 5: "5 or more", 6: "no room found"}.get(key, str(key))
        base = [r["p_baseline"] for r in rs if r["p_baseline"] is not None]
        push = [r["p_push"] for r in rs if r["p_push"] is not None]
        travel = [sum(c["travel"] for c in r["cleared"]) for r in rs]
        lines.append(f"| {label} | {len(rs)} | {np.mean(base) if base else float('nan'):.2f} | "
                     f"{np.mean(push) if push else float('nan'):.2f} | "
                     f"{np.median(travel):.3f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db")
    parser.add_argument("--env", default="fridge")
    parser.add_argument("--levels", type=int, nargs="+", default=[12, 16])
    parser.add_argument("--limit", type=int, default=0)
    parser.add_argument("--deep", type=float, default=0.005, help="m")
    parser.add_argument("--step", type=float, default=0.005, help="m")
    parser.add_argument("--travel", type=float, default=0.2, help="m")
    parser.add_argument("--directions", type=int, default=16)
    parser.add_argument("--chain", type=int, default=3)
    parser.add_argument("--push-only", action="store_true",
                        help="no direction back toward the robot")
    parser.add_argument("--out", help="JSON-lines file of the results")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--from", dest="stored", nargs="+",
                        help="JSON-lines files of earlier results: print their tables only")
    args = parser.parse_args(argv)
    if args.stored:
        try:
            results = [json.loads(line) for path in args.stored
                       for line in open(path, encoding="utf-8") if line.strip()]
        except (OSError, json.JSONDecodeError) as err:
            print(f"grasp_room: --from: {err}", file=sys.stderr)
            return 2
        print(table(results))
        print(by_moves(results))
        return 0
    if not args.db:
        print("grasp_room: --db STORE.db is required (or --from FILE.jsonl)", file=sys.stderr)
        return 2
    try:
        config = load_config(None, args.overrides)
        rows = baseline_rows(args.db, args.env, args.levels, args.limit)
    except InputError as err:
        print(err, file=sys.stderr)
        return 2
    if not (args.step > 0 and args.travel >= args.step and args.directions > 0
            and args.chain > 0 and args.deep >= 0):
        print("grasp_room: --step, --travel, --directions, --chain must be positive, "
              "--travel >= --step, --deep >= 0", file=sys.stderr)
        return 2
    results = []
    for row in rows:
        r = initialization(row, config, args)
        print(line(r), flush=True)
        results.append(r)
        if args.out:
            with open(args.out, "a", encoding="utf-8") as f:
                f.write(json.dumps(r) + "\n")
    print(table(results))
    print(by_moves(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
