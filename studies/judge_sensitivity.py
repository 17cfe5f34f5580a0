#!/usr/bin/env python3
"""How sensitive is the Bullet judge (Sec. III) to the last digits of a plan?

    python studies/judge_sensitivity.py [--db RUN.db [--configurations NAME ...]]
        [--scenes NAME ...] [--angles I ...] [--eps E ...] [--replicas R] [--seed S]
        [--set FIELD=VALUE ...]

Every plan is replayed in Bullet as it is, then ``--replicas`` times with each interior knot's
seven arm joints moved by eps x a seeded standard normal (rad; the first and last knots and
the gripper left alone), for each ``--eps``. Printed per plan: its grade (Sec. VI-A's class,
then boxes tipped or fallen: `scene.grading.behaviour_grade`) and the replicas' grades; then per
planner and eps, how many replays changed grade. Without ``--db``: the baseline's plans of the
shipped behaviour scenes at the given angle indices, each angle planned alone (as an
experiment unit plans it). With ``--db``: every stored plan of a shipped scene in that
experiment store (physics and baseline), and for each physics row that has a baseline row of
the same initialization, how often the replicas' verdict (better / same / worse) matches the
stored one - i.e. whether a comparison of two single plans is a measurement or a draw.

Its dated results: docs/log/decisions.md, docs/log/evaluation.md, docs/log/physics_planner.md.
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.evaluation.outcome import outcome_grade
from drake_clutter.experiments.paired import verdict
from drake_clutter.experiments.specs import load_spec, plan_one_angle
from drake_clutter.experiments.store import Store
from drake_clutter.scene import scenes
from drake_clutter.trajectory import Trajectory

BEHAVIOUR_SCENES = load_spec("behaviours")[0].shipped  # Sec. VI-A's four scenes, one list


def jittered(trajectory: Trajectory, eps: float, seed: int) -> Trajectory:
    """The trajectory with its interior knots' arm joints moved by eps x N(0, 1) (rad)."""
    q = trajectory.q.copy()
    q[1:-1, :7] += eps * np.random.default_rng(seed).standard_normal(q[1:-1, :7].shape)
    return Trajectory(trajectory.times, q, trajectory.joint_names)


def plans(args, config) -> list[dict]:
    """[{scene, planner, configuration, angle, trajectory}] to judge."""
    if args.db:
        shipped = set(scenes.shipped_scene_names())
        with Store(args.db, read_only=True) as store:
            rows = store.rows()
        return [{"scene": r["scene"], "planner": r["planner"], "configuration": r["config_name"],
                 "angle": r["angle"], "trajectory": Trajectory.from_data(r["plan"]["trajectory"])}
                for r in rows if r["scene"] in shipped and r["plan"]
                and r["plan"].get("trajectory")
                and (not args.configurations or r["config_name"] in args.configurations)]
    out = []
    for name in args.scenes:
        scene = scenes.load_shipped_scene(name)
        for angle in args.angles:
            candidate = plan_one_angle(scene, config, "baseline", angle)
            if candidate.ok:
                out.append({"scene": name, "planner": "baseline", "configuration": "-",
                            "angle": angle, "trajectory": candidate.trajectory})
    return out


def judge(plan: dict, args, config, cache: dict) -> dict:
    """{eps: [grade of each replica]} and the plan's own grade under key None."""
    if plan["scene"] not in cache:
        cache[plan["scene"]] = scenes.load_shipped_scene(plan["scene"])
    scene = cache[plan["scene"]]
    grades = {None: outcome_grade(evaluate(scene, plan["trajectory"], config.evaluation))}
    for eps in args.eps:
        grades[eps] = [outcome_grade(evaluate(scene, jittered(plan["trajectory"], eps,
                                                               args.seed + r), config.evaluation))
                       for r in range(args.replicas)]
    return grades


def report(judged: list[tuple[dict, dict]], args) -> None:
    changed, total = Counter(), Counter()
    for plan, grades in judged:
        for eps in args.eps:
            key = (plan["planner"], plan["configuration"], eps)
            changed[key] += sum(g != grades[None] for g in grades[eps])
            total[key] += len(grades[eps])
    for key in total:
        print(f"{key[0]} ({key[1]}), eps {key[2]:g} rad: grade changed in {changed[key]} of "
              f"{total[key]} replays")
    base = {(p["configuration"], p["scene"], p["angle"]): g for p, g in judged
            if p["planner"] == "baseline"}
    agree, pairs = Counter(), Counter()
    for plan, grades in judged:
        b = base.get((plan["configuration"], plan["scene"], plan["angle"]))
        if plan["planner"] != "physics" or b is None:
            continue
        stored = verdict(grades[None], b[None])
        for eps in args.eps:
            for gp, gb in zip(grades[eps], b[eps], strict=True):
                agree[(plan["configuration"], eps)] += verdict(gp, gb) == stored
                pairs[(plan["configuration"], eps)] += 1
    for key in pairs:
        print(f"physics vs baseline ({key[0]}), eps {key[1]:g} rad: the replicas' verdict "
              f"matches the unperturbed one in {agree[key]} of {pairs[key]}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", help="an experiment store whose plans to judge")
    parser.add_argument("--configurations", nargs="+", default=[],
                        help="with --db: only these configurations' rows (default: all)")
    parser.add_argument("--scenes", nargs="+", default=list(BEHAVIOUR_SCENES))
    parser.add_argument("--angles", nargs="+", type=int, default=[4, 5, 6, 7, 8, 9])
    parser.add_argument("--eps", nargs="+", type=float, default=[1e-6, 1e-3])
    parser.add_argument("--replicas", type=int, default=3)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args(argv)
    config = load_config(None, args.set)
    judged, cache = [], {}
    for plan in plans(args, config):
        grades = judge(plan, args, config, cache)
        judged.append((plan, grades))
        print(f"{plan['scene']} angle {plan['angle']} {plan['planner']} "
              f"({plan['configuration']}): {grades[None]} | "
              + " | ".join(f"eps {e:g}: {grades[e]}" for e in args.eps), flush=True)
    report(judged, args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
