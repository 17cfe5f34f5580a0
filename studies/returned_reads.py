#!/usr/bin/env python3
"""phi's reading of the path the push planner returned, against the judge's replays.

    python studies/returned_reads.py STORE.db [STORE.db ...] [--configurations NAME ...]
        [--examples 5] [--trace K]

Reads stored units only (no simulation). For every push unit with a plan, a robust replay
and phi's verdict on the returned path (the search's record, ``details.search.verdicts``):

* the confusion matrix of phi's nominal member (member 0) against the judge's nominal replay
  (rows the judge, columns phi), overall and by where the path came from (a straight start,
  a bent path, the baseline's path); 95 % Wilson interval on the accuracy;
* phi's P(success) over its members against the robust judge's, as a table of means and
  the share of paths phi reads as a success in every member that the judge does not;
* the "tipping misread": paths phi reads as a success in every member while the judge's
  nominal replay tips or drops a box (a partial success or objects falling), with the boxes
  the judge saw disturbed; ``--examples`` of them listed.

``--trace K`` rolls out again the K tipping misreads the judge is surest of (lowest robust
P(success)) and prints, for each box the judge's nominal replay disturbed, its tilt (rad) and
displacement (m) at the end: in Bullet (stored); in the judge in phi's nominal member
(`phi_judge.judged_rollouts`, the defaults' phi, its pruned world: a box it did not keep
stays at rest); and in phi with every box dynamic (`testing.fidelity.phi_final`, the judge in phi's
engine, the hold as settling) with the planner's capsule arm and with the judge's mesh arm
(a diagnosis only: no planner plans with the mesh arm).

Units whose returned path has no phi verdict are counted by why, not read: a clear start
(the arm touches no box, so the planner rolls nothing out; the judge's classes of these are
printed apart), the baseline's path as the fallback (the search's pick read no success or
partial in phi) or after a spent budget, no plan.

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter

import numpy as np

from drake_clutter.experiments.paired import wilson_interval
from drake_clutter.experiments.store import Store
from drake_clutter.scene.grading import OUTCOME_KINDS

KINDS = OUTCOME_KINDS[:5]  # the five classes of Sec. III
SHORT = {"success": "S", "partial_success": "PS", "failure_to_grasp": "FG",
         "objects_falling": "OF", "kinematic_failure": "KF"}


def source_of(chosen: str) -> str:
    """Where a returned path came from, by the search's naming: "start" (a straight start at
    one grasp height, named by the height), "bent" (a drawn member, "<start>/r<round>m<i>")."""
    return "bent" if "/" in chosen else "start"


def read_unit(row: dict) -> dict | None:
    """One push unit's returned path: phi's member classes and P(success), the judge's
    nominal class, robust classes and P(success), the boxes the nominal replay disturbed (their
stored records);
    None when the unit has no plan, no robust replay or no phi verdict on its path."""
    outcome = row.get("outcome") or {}
    robust = outcome.get("robust")
    details = ((row.get("plan") or {}).get("details") or {})
    search = details.get("search") or {}
    chosen = search.get("chosen")
    if chosen != details.get("chosen"):  # the baseline's path came back: phi never read it
        return None
    verdict = (search.get("verdicts") or {}).get(chosen) if chosen else None
    if not robust or verdict is None or outcome.get("kind") not in KINDS:
        return None
    disturbed = [b for b in outcome.get("boxes", []) if b.get("tipped") or b.get("fallen")]
    return {"scene": row["scene"], "angle": row["angle"], "config": row["config_name"],
            "source": source_of(chosen), "chosen": chosen,
            "phi": verdict["kinds"], "phi_p": float(verdict["p_success"]),
            "judge": outcome["kind"], "judge_p": float(robust["p_success"]),
            "robust": robust["kinds"], "disturbed": disturbed,
            "reason": outcome.get("reason", ""),
            "trajectory": (row.get("plan") or {}).get("trajectory")}


def skip_reason(row: dict) -> str:
    """Why a push unit has no phi reading of its returned path, with the judge's nominal
    class of the path where it was replayed."""
    details = ((row.get("plan") or {}).get("details") or {})
    kind = (row.get("outcome") or {}).get("kind", "none")
    if not (row.get("plan") or {}).get("trajectory"):
        return f"no plan ({kind})"
    if details.get("chosen") in details.get("clear", ()):
        return f"clear start, judged {kind}"
    if details.get("chosen") == "baseline":
        return f"the baseline's path as the fallback, judged {kind}"
    return f"other, judged {kind}"


def load(dbs: list[str], configurations: list[str]) -> tuple[list[dict], Counter]:
    """The readable push units of the stores, and a count of the units skipped, by reason."""
    reads, skipped = [], Counter()
    for db in dbs:
        with Store(db, read_only=True) as store:
            rows = store.rows()
        for row in rows:
            if row["planner"] != "push" or (configurations
                                            and row["config_name"] not in configurations):
                continue
            read = read_unit(row)
            if read is not None:
                reads.append(read)
                continue
            skipped[skip_reason(row)] += 1
    return reads, skipped


def print_confusion(reads: list[dict], title: str) -> None:
    """Rows: the judge's nominal class; columns: phi's nominal member's class."""
    table = Counter((r["judge"], r["phi"][0]) for r in reads)
    print(f"\n{title}: {len(reads)} paths (rows the judge's nominal replay, columns phi's "
          f"nominal member)")
    print(f"{'':>18} " + " ".join(f"{SHORT[k]:>5}" for k in KINDS) + f" {'recall':>7}")
    for j in KINDS:
        row = [table[(j, k)] for k in KINDS]
        total = sum(row)
        recall = f"{table[(j, j)] / total:.2f}" if total else "-"
        print(f"{j:>18} " + " ".join(f"{v:>5}" for v in row) + f" {recall:>7}")
    right = sum(table[(k, k)] for k in KINDS)
    low, high = wilson_interval(right, len(reads))
    print(f"accuracy {right}/{len(reads)} = {right / max(len(reads), 1):.2f} "
          f"[{low:.2f}, {high:.2f}]")


def print_probabilities(reads: list[dict]) -> None:
    """phi's P(success) against the robust judge's, by source."""
    print("\nP(success): phi's members against the robust judge's replays")
    print(f"{'source':>8} {'paths':>6} {'phi':>6} {'judge':>6} {'phi 1, judge < 0.5':>19}")
    for source in ("start", "bent", "all"):
        rs = [r for r in reads if source in ("all", r["source"])]
        if not rs:
            continue
        over = sum(r["phi_p"] == 1.0 and r["judge_p"] < 0.5 for r in rs)
        print(f"{source:>8} {len(rs):>6} {sum(r['phi_p'] for r in rs) / len(rs):>6.3f} "
              f"{sum(r['judge_p'] for r in rs) / len(rs):>6.3f} {over:>19}")


def tipping_misreads(reads: list[dict]) -> list[dict]:
    """Paths phi reads as a success in every member whose nominal replay disturbs a box,
    the judge's surest (lowest robust P(success)) first."""
    return sorted((r for r in reads if r["phi_p"] == 1.0
                   and r["judge"] in ("partial_success", "objects_falling")),
                  key=lambda r: r["judge_p"])


def print_tipping(reads: list[dict], examples: int) -> None:
    """Paths phi reads as a success in every member whose nominal replay disturbs a box."""
    misread = tipping_misreads(reads)
    success = [r for r in reads if r["phi_p"] == 1.0]
    print(f"\nphi reads success in every member: {len(success)} paths; the judge's nominal "
          f"replay disturbs a box in {len(misread)} of them "
          f"({Counter(r['judge'] for r in misread)})")
    by_source = Counter(r["source"] for r in misread)
    print(f"  by source: {dict(by_source)}; robust P(success) of these: mean "
          f"{sum(r['judge_p'] for r in misread) / max(len(misread), 1):.3f}")
    for r in misread[:examples]:
        print(f"  {r['config']} {r['scene']} angle {r['angle']} {r['chosen']}: judge "
              f"{Counter(r['robust'])}, disturbed {[b['name'] for b in r['disturbed']]} "
              f"({r['reason']})")


def trace(read: dict) -> None:
    """One misread path rolled out again in phi: each box the judge's nominal replay
    disturbed, at the end in Bullet, in the judge in phi's nominal member, and in phi with
    every box dynamic and the capsule arm, then the judge's mesh arm (see the module
    docstring)."""
    from drake_clutter.common.config import load_config
    from drake_clutter.experiments.specs import stored_scene
    from drake_clutter.phi.state import scene_box_states
    from drake_clutter.planners.context import PlanningContext
    from drake_clutter.planners.phi_judge import box_fates, judged_rollouts
    from drake_clutter.scene.grading import tilt_angle
    from drake_clutter.testing.fidelity import phi_final
    from drake_clutter.trajectory import Trajectory

    config = load_config()
    scene = stored_scene(read["scene"], config)
    path = Trajectory.from_data(read["trajectory"])
    knot_time = float(np.diff(path.times[:2])[0])
    final = judged_rollouts(scene, {"path": path.q}, config, knot_time)["path"].final_boxes
    p, R, _, _ = box_fates(scene, PlanningContext(scene, config).arm(), final or {},
                           config.evaluation)
    judged = {"judge in phi": (tilt_angle(R), p)}
    dyn = load_config(None, [f"dynamics.engine={config.phi_judge.engine}"])
    hold = config.phi_judge.hold_knots * knot_time
    for arm in ("capsules", "evaluation"):
        f = phi_final(scene, path, dyn, hold, arm)
        judged[f"{arm} arm, every box dynamic"] = (f.tilts, f.positions)
    rest = np.array([state[4:7] for state in scene_box_states(scene).values()])
    names = [b.name for b in scene.boxes]
    print(f"  {read['config']} {read['scene']} angle {read['angle']} {read['chosen']} "
          f"(robust P(success) {read['judge_p']:.3f}; phi's rollout "
          f"{'failed' if final is None else 'finished'}); tilt rad / moved m")
    for box in read["disturbed"]:
        i = names.index(box["name"])
        phi = "; ".join(f"{label} {tilts[i]:.2f} / {np.linalg.norm(ps[i] - rest[i]):.3f}"
                        for label, (tilts, ps) in judged.items())
        print(f"    {box['name']}: Bullet {box['tilt']:.2f} / {box['displacement']:.3f}; {phi}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dbs", nargs="+", help="stores holding push units")
    parser.add_argument("--configurations", nargs="*", default=[],
                        help="read only these configurations (default: all)")
    parser.add_argument("--examples", type=int, default=5,
                        help="misread paths listed (default 5)")
    parser.add_argument("--trace", type=int, default=0,
                        help="tipping misreads rolled out again in phi (default 0)")
    args = parser.parse_args(argv)
    try:
        reads, skipped = load(args.dbs, args.configurations)
    except (OSError, ValueError) as error:
        print(f"returned_reads: {error}", file=sys.stderr)
        return 2
    print(f"read {len(reads)} push units; not read:")
    for reason, count in sorted(skipped.items()):
        print(f"  {count:>4}  {reason}")
    if not reads:
        return 0
    print_confusion(reads, "all returned paths")
    for source in ("start", "bent"):
        rs = [r for r in reads if r["source"] == source]
        if rs:
            print_confusion(rs, f"returned {source} paths")
    print_probabilities(reads)
    print_tipping(reads, args.examples)
    if args.trace:
        print(f"\nthe {args.trace} surest tipping misreads, rolled out again in phi's nominal "
              "member:")
        for read in tipping_misreads(reads)[:args.trace]:
            trace(read)
    return 0


if __name__ == "__main__":
    sys.exit(main())
