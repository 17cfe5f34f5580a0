#!/usr/bin/env python3
"""The main job: plan a scene, evaluate the plans in Bullet, replay them side by side in Meshcat.

    python apps/plan_scene.py                         # the default shipped scene, served live
    python apps/plan_scene.py --scene fig7_cascade    # a shipped scene by name, or a YAML file
    python apps/plan_scene.py --html out.html         # write a self-contained HTML file instead
    python apps/plan_scene.py --picture out.png --no-browser   # and a picture of the replay
    python apps/plan_scene.py --planner baseline      # one planner only (baseline: seconds)
    python apps/plan_scene.py --scene dense_rearrange --planner baseline push rearrange \
        --angles 14 --angle 8                          # three planners, one angle of 14
    python apps/plan_scene.py --planner physics --iterations 30   # the paper's Sec. V (slow)

The baseline (Sec. IV) plans ``--angles`` approach angles; ``--planner both`` (the default)
also runs the planner compared with it, the push planner (a sampling search over paths that can
push, scored by the judge in phi, started from the baseline's paths; ``push`` shows only its
plans). ``--planner physics`` is the paper's Sec. V (iLQR through phi from the baseline's paths;
``--iterations`` sets its iterations through phi); ``rearrange`` pushes the boxes crowding the
grasp aside before the push planner's reach. Several names plan and show each (a planner started
from another reuses its plans); ``--angle I`` plans the I-th angle of the ``--angles`` grid
alone. Every plan is replayed in Bullet (Sec. III)
with a recording. A table prints, per angle, each planner's outcome and planning time. Meshcat
then replays the chosen angle, the plans side by side (the last planner named first, on the
right, the baseline on the left; the boxes move as Bullet moved them, tipped boxes orange,
fallen red, contact forces as yellow arrows; drake_clutter/viz/replay.py): the angle with the
best outcome of the compared planner among those both planners made a plan for (ties: the better
baseline outcome, then the first); with ``--show selected``, each planner's own choice, the
candidate it would execute ranked without the judge (starred in the table;
drake_clutter/planners/selection.py). Cost curves of Sec. V's plans (each term per iLQR
iteration) go to PNG files. Prints the Meshcat URL and serves until Ctrl-C unless --html or
--no-browser is given. Bad input prints one line and exits 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_clutter.common.arguments import OneLineParser
from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.evaluation.outcome import OUTCOME_KINDS
from drake_clutter.phi.mujoco_model import check_scene
from drake_clutter.planners.registry import (
    ALL_PLANNERS,
    COMPARED,
    PhysicsPlanner,
    check_planners,
    get_planner,
    named_planners,
    planner_names,
    run_planners,
)
from drake_clutter.planners.selection import selected_index
from drake_clutter.robot.pr2 import VARIANTS
from drake_clutter.scene.scenes import DEFAULT_SCENE, resolve_scene

# Best first: the order in which an outcome is preferred for the Meshcat replay.
_RANK = OUTCOME_KINDS


def with_iterations(config, iterations: int | None):
    """``config`` with ``iterations`` physics iterations through phi, a third of them with
    the sphere proxy (Sec. V: 10 of 30); None: ``config`` as it is."""
    if iterations is None:
        return config
    physics = dataclasses.replace(config.physics, iterations=iterations,
                                  sphere_iterations=round(iterations / 3))
    return dataclasses.replace(config, physics=physics)


def _plan(scene, config, names: tuple, angles: int, index: int | None = None) -> dict:
    """{planner: (candidates, Bullet outcomes with recordings)} of every one of ``angles``
    approach angles in a row (the baseline seeding each angle's IK with its neighbour's
    solution), or of angle ``index`` alone (as an experiment's work unit plans it)."""
    from drake_clutter.evaluation.judge import evaluate_candidates

    plans = run_planners(scene, config, names, angles=None if index is None else [index],
                         num_angles=angles)
    return {name: (candidates, evaluate_candidates(scene, candidates, config.evaluation,
                                                   record_fps=config.viz.fps))
            for name, candidates in plans.items()}


def shown_planners(planners: list[str]) -> tuple[str, ...]:
    """The planners named on the command line ("both": `registry.COMPARED`), each once, in the
    order shown: the last named first (on the right)."""
    return named_planners(planners)[::-1]


def plan_and_evaluate(scene, config, angles: int, names: tuple[str, ...] = COMPARED[::-1],
                      jobs: int = 1, only: int | None = None) -> dict:
    """{planner: (candidates, Bullet outcomes with recordings)} for ``angles`` approach angles
    (``only``: the angle of that index alone), the planners ``names`` in the order shown. With
    ``jobs`` > 1 the angles are planned in that many processes, each angle alone and phi's
    derivatives serial within it (``dynamics.workers`` 0: the same plans, the line search
    accepts the step a batched one would)."""
    if only is not None:
        return _plan(scene, config, names, angles, only)
    if jobs <= 1 or angles <= 1:
        return _plan(scene, config, names, angles)
    serial = dataclasses.replace(
        config, dynamics=dataclasses.replace(config.dynamics, workers=0))
    with ProcessPoolExecutor(min(jobs, angles),
                             mp_context=multiprocessing.get_context("spawn")) as pool:
        parts = list(pool.map(_plan, *zip(*[(scene, serial, names, angles, i)
                                            for i in range(angles)], strict=True)))
    return {name: ([c for part in parts for c in part[name][0]],
                   [o for part in parts for o in part[name][1]]) for name in names}


def selections(plans: dict, config) -> dict[str, int | None]:
    """Per planner, the angle index of the candidate it would execute, chosen without the
    judge (`planners.selection.selected_index`), or None."""
    return {name: selected_index(candidates, config)
            for name, (candidates, _) in plans.items()}


def outcome_table(plans: dict, selected: dict[str, int | None] | None = None) -> str:
    """One row per angle: each planner's outcome kind and planning time (s), a '*' on the
    candidate it would execute (``selected``), and the seconds per stage of the planner shown
    first."""
    names = list(plans)
    selected = selected or {}
    header = f"{'alpha':>7}  " + "  ".join(f"{n:19} {'s':>6}" for n in names)
    rows = [header + f"  {names[0]} stages (s)"]
    for i, first in enumerate(plans[names[0]][0]):
        cells = []
        for name in names:
            candidate, outcome = plans[name][0][i], plans[name][1][i]
            mark = "*" if selected.get(name) == i else " "
            cells.append(f"{outcome.kind:18}{mark} {sum(candidate.timings.values()):6.1f}")
        stages = "  " + " ".join(f"{k}={v:.1f}" for k, v in first.timings.items())
        rows.append(f"{first.alpha:+7.3f}  " + "  ".join(cells) + stages)
    if selected:
        rows.append("* the candidate each planner would execute (ranked without the judge): "
                    + ", ".join(f"{n} " + ("none" if selected.get(n) is None else
                                           f"alpha {plans[n][0][selected[n]].alpha:+.3f} "
                                           f"({plans[n][1][selected[n]].kind})")
                                for n in names))
    return "\n".join(rows)


def choose_angle(plans: dict) -> tuple[int, list[str]] | None:
    """(angle index, planners with a usable plan there) to replay: among the angles where every
    planner made a plan, the best outcome of the first planner shown, ties going to the angle
    where the next ones did worst (where the first planner's plan differs most), then the
    first angle; else the best angle of any single planner; None when no plan is usable."""
    names = list(plans)
    count = len(plans[names[0]][0])

    def rank(i, among):
        first, *others = (_RANK.index(plans[n][1][i].kind) for n in among)
        return (first, *(-k for k in others), i)

    usable = {i: [n for n in names if plans[n][0][i].ok] for i in range(count)}
    full = [i for i in range(count) if len(usable[i]) == len(names)]
    if full:
        best = min(full, key=lambda i: rank(i, names))
        return best, names
    partial = [(rank(i, usable[i]), i) for i in range(count) if usable[i]]
    if not partial:
        return None
    best = min(partial)[1]
    return best, usable[best]


def write_cost_curves(plans: dict, directory: Path, stem: str) -> list[Path]:
    """A PNG of cost curves per plan whose planner's record has an iLQR history (Sec. V's):
    ``<directory>/<stem>_costs_<planner>_<alpha>.png``."""
    from drake_clutter.viz.cost_curves import plot_cost_curves

    written = []
    for candidate in (c for candidates, _ in plans.values() for c in candidates):
        path = directory / f"{stem}_costs_{candidate.planner}_{candidate.alpha:+.3f}.png"
        stages = get_planner(candidate.planner).record(candidate.details).histories()
        title = f"{candidate.planner} plan, alpha = {candidate.alpha:+.3f} rad"
        if plot_cost_curves(stages, path, title) is not None:
            written.append(path)
    return written


def replay(scene, config, plans: dict, choice, variant: str, html: str | None,
           wait: bool, picture: str | None = None) -> None:
    """Replays the chosen plans side by side in Meshcat (or shows the scene when no plan is
    usable), then writes ``html`` or serves (until Ctrl-C when ``wait``); with ``picture``,
    also a PNG of 4 instants of the replay (`viz.pictures.frame_strip`). ``choice``: (angle
    index, planners) - one angle for all, `choose_angle` - or {planner: angle index} - each
    planner's own, `selections`."""
    from pydrake.geometry import Meshcat

    from drake_clutter.viz.replay import PlanView, record_replay
    from drake_clutter.viz.views import show_scene, write_static_html

    if choice is None:
        print("no usable plan: showing the scene")
        show_scene(scene, config, variant=variant, html=html, wait=wait)
        return
    per = choice if isinstance(choice, dict) else dict.fromkeys(choice[1], choice[0])
    views = [PlanView(n, plans[n][0][i], plans[n][1][i]) for n, i in per.items()]
    if picture:
        from drake_clutter.viz.pictures import frame_strip

        title = f"{scene.name}: " + ", ".join(f"{v.label} alpha {v.candidate.alpha:+.3f}"
                                              for v in views)
        print(f"wrote {frame_strip(scene, views, config, picture, title=title, variant=variant)}")
    meshcat = Meshcat()
    summary = record_replay(scene, views, config, meshcat, variant)
    sides = ("right", "left") if len(views) == 2 else tuple(f"copy {i}" for i in range(len(views)))
    print(f"replay ({summary.duration:.1f} s): " +
          ", ".join(f"{v.label} alpha {v.candidate.alpha:+.3f} ({v.outcome.kind}) {side} at {p}"
                    for v, side, p in zip(views, sides, summary.paths, strict=True)))
    if html:
        print(f"wrote {write_static_html(meshcat, html)}")
        return
    print(f"Meshcat: {meshcat.web_url()}", flush=True)
    if wait:
        print("serving; Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=DEFAULT_SCENE,
                        help=f"shipped scene name or YAML file (default: {DEFAULT_SCENE})")
    parser.add_argument("--planner", nargs="+", choices=(*planner_names(), ALL_PLANNERS),
                        default=[ALL_PLANNERS],
                        help="which plans to make and show, one or more (default: both)")
    parser.add_argument("--html", help="write a self-contained HTML file instead of serving "
                        "(cost curves go next to it)")
    parser.add_argument("--picture", metavar="PNG",
                        help="also write a picture of 4 instants of the replay (headless "
                        "Chromium)")
    parser.add_argument("--costs", metavar="DIR",
                        help="directory for the cost-curve PNGs (default: that of --html; "
                        "none are written when serving without --costs)")
    parser.add_argument("--show", choices=("best", "selected"), default="best",
                        help="replay the angle with the best outcome in Bullet (default), or "
                        "the candidate each planner would execute, chosen without the judge")
    parser.add_argument("--variant", choices=VARIANTS, default="capsules",
                        help="arm geometry drawn in Meshcat (default: capsules)")
    parser.add_argument("--no-browser", action="store_true",
                        help="publish once and exit instead of serving until interrupted")
    parser.add_argument("--angles", type=int, default=2,
                        help="approach angles to plan (default 2; the paper uses 14)")
    parser.add_argument("--angle", type=int, default=None, metavar="INDEX",
                        help="plan only this angle of the --angles grid (0-based)")
    parser.add_argument("--iterations", type=int, default=None,
                        help="Sec. V's iLQR iterations through phi per candidate, a third with "
                        "the sphere proxy, for --planner physics (default: the "
                        "configuration's, 0: no phi stages; the paper's: --iterations 30)")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                        help="processes planning the angles side by side, each angle alone "
                        "(default: 2, or 1 on one core; 1: every angle in a row, the baseline "
                        "seeding each angle's IK with its neighbour's solution)")
    parser.add_argument("--config", help="YAML configuration overrides")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    return parser


def _check(args) -> None:
    if args.angles < 1:
        raise InputError("<command line>", "--angles", f"must be at least 1, got {args.angles}")
    if args.jobs < 1:
        raise InputError("<command line>", "--jobs", f"must be at least 1, got {args.jobs}")
    if args.iterations is not None and args.iterations < 0:
        raise InputError("<command line>", "--iterations",
                         f"must be at least 0, got {args.iterations}")
    if args.angle is not None and not 0 <= args.angle < args.angles:
        raise InputError("<command line>", "--angle",
                         f"must be in [0, {args.angles - 1}] (--angles {args.angles}), "
                         f"got {args.angle}")
    if args.iterations is not None and PhysicsPlanner.name not in args.planner:
        raise InputError("<command line>", "--iterations",
                         "sets Sec. V's iterations through phi: give it with --planner physics")
    for flag, value in (("--html", args.html), ("--costs", args.costs),
                        ("--picture", args.picture)):
        if value is None:
            continue
        folder = Path(value) if flag == "--costs" else Path(value).parent
        if not folder.is_dir():
            raise InputError(value, flag, f"no such directory: {folder}")
    if args.picture is not None:
        from drake_clutter.viz.screenshot import ChromiumMissing, chromium_path

        try:
            chromium_path()  # checked before planning: the picture needs it at the end
        except ChromiumMissing as exc:
            raise InputError("<command line>", "--picture", str(exc)) from None


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        _check(args)
        config = with_iterations(load_config(args.config, args.overrides), args.iterations)
        scene = resolve_scene(args.scene)
        if config.dynamics.engine == "mujoco":
            check_scene(scene, args.scene)
        names = shown_planners(args.planner)
        check_planners(config, names, args.config or "<command line>")
        plans = plan_and_evaluate(scene, config, args.angles, names, args.jobs, args.angle)
        selected = selections(plans, config)
        print(outcome_table(plans, selected))
        costs = args.costs or (str(Path(args.html).parent) if args.html else None)
        if costs is not None:
            stem = Path(args.html).stem if args.html else scene.name
            for path in write_cost_curves(plans, Path(costs), stem):
                print(f"wrote {path}")
        if args.show == "selected":
            choice = {n: i for n, i in selected.items() if i is not None} or None
        else:
            choice = choose_angle(plans)
        replay(scene, config, plans, choice, args.variant, args.html,
               wait=not args.html and not args.no_browser, picture=args.picture)
    except InputError as exc:
        print(f"plan_scene: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=3, suppress=True)
    sys.exit(main())
