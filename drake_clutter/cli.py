"""The ``drake-clutter`` command line.

Subcommands:
  scene generate --kind bookshelf|fridge --objects N --seed S -o FILE
  scene validate FILE
  scene show FILE|NAME [--html FILE] [--variant V]
  scene list
  plan SCENE --planner baseline|physics|push|both [--angles K] --out PLAN.json
  evaluate SCENE PLAN.json [--lift] [--robust K] [--seed S] --out OUTCOMES.json
  experiment run SPEC|TIER --db RUN.db [--workers N] [--executor local|ray]
  experiment rejudge RUN.db --db NEW.db [--set evaluation.FIELD=VALUE ...]
  experiment digests TIER|bench ... [--out FILE] | --compare OLD NEW
  stores compare A.db B.db ... --against CONFIGURATION/PLANNER
  report RUN.db --out DIR
  config show [--config FILE] [--set key=value ...]

Bad input (a scene file, a config file, an argument) prints one line naming the problem on
stderr and exits with status 2; there is never a traceback for user errors.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from drake_clutter.common.arguments import OneLineParser
from drake_clutter.common.processes import Terminated, interrupt_on_sigterm
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.scene.generators import GenerationError


def _add_config_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", help="YAML file overriding the default configuration")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE",
                        help="override one setting, e.g. world.time_step=0.005")


def _load_config(args):
    from drake_clutter.common.config import load_config

    return load_config(args.config, args.overrides)


def _cmd_scene_generate(args) -> int:
    from drake_clutter.scene.generators import generate_scene
    from drake_clutter.scene.scenes import save_scene

    config = _load_config(args)
    if args.objects < 1:
        raise InputError("<command line>", "--objects", f"must be at least 1, got {args.objects}")
    if args.seed < 0:
        raise InputError("<command line>", "--seed", f"must be non-negative, got {args.seed}")
    try:
        scene = generate_scene(args.kind, args.objects, args.seed, config.generator)
    except GenerationError as exc:
        raise InputError("<command line>", "--objects", f"{args.objects} boxes do not fit on "
                         f"the {args.kind} board: {exc}") from None
    path = save_scene(scene, args.output)
    print(f"wrote {path} ({len(scene.boxes)} boxes, {scene.shelf.kind})")
    return 0


def _cmd_scene_validate(args) -> int:
    from drake_clutter.scene.scenes import load_scene

    scene = load_scene(args.file)
    print(f"{args.file}: ok ({scene.shelf.kind}, {len(scene.boxes)} boxes, target "
          f"'{scene.target}')")
    return 0


def _cmd_scene_list(args) -> int:
    from drake_clutter.scene.scenes import load_shipped_scene, shipped_scene_names

    for name in shipped_scene_names():
        scene = load_shipped_scene(name)
        summary = scene.description.splitlines()[0] if scene.description else ""
        print(f"{name:22s} {scene.shelf.kind:9s} {len(scene.boxes):3d} boxes  {summary}")
    return 0


def _cmd_scene_show(args) -> int:
    from drake_clutter.scene.scenes import resolve_scene
    from drake_clutter.viz.views import show_scene

    config = _load_config(args)
    scene = resolve_scene(args.scene)
    show_scene(scene, config, variant=args.variant, html=args.html,
               wait=not args.html and not args.no_wait)
    return 0


def _cmd_evaluate(args) -> int:
    import dataclasses
    import json

    from drake_clutter.common.config import check_config
    from drake_clutter.evaluation.judge import (
        check_plan,
        evaluate_candidates,
        outcome_table,
        outcomes_document,
    )
    from drake_clutter.scene.scenes import resolve_scene
    from drake_clutter.trajectory import load_plan

    config = _load_config(args)
    evaluation = config.evaluation
    if args.robust is not None:
        if args.robust < 1:
            raise InputError("<command line>", "--robust", f"must be at least 1, got "
                                                           f"{args.robust}")
        evaluation = dataclasses.replace(evaluation, robust_replays=args.robust)
    if args.seed is not None:
        if args.seed < 0:
            raise InputError("<command line>", "--seed", f"must be non-negative, got {args.seed}")
        evaluation = dataclasses.replace(evaluation, robust_seed=args.seed)
    check_config(evaluation, args.config or "<command line>", "evaluation")
    scene = resolve_scene(args.scene)
    plan_scene, candidates, _ = load_plan(args.plan)
    check_plan(scene, plan_scene, candidates, args.plan)
    if not Path(args.out).resolve().parent.is_dir():
        raise InputError("<command line>", "--out", f"no such directory for {args.out}")
    outcomes = evaluate_candidates(scene, candidates, evaluation, lift=args.lift)
    doc = outcomes_document(scene, candidates, outcomes, args.plan)
    try:
        Path(args.out).write_text(json.dumps(doc, indent=1), encoding="utf-8")
    except OSError as exc:
        raise InputError("<command line>", "--out", f"cannot write {args.out}: {exc.strerror}") \
            from None
    print(outcome_table(candidates, outcomes))
    print(f"scene score: {doc['scene_score']} ({scene.name}, {len(candidates)} candidates); "
          f"wrote {args.out}")
    return 0


def _check_scene_for_engine(scene, config, file: str) -> None:
    """SceneError where phi's engine cannot express the scene (MuJoCo's least friction, mass)."""
    if config.dynamics.engine == "mujoco":
        from drake_clutter.phi.mujoco_model import check_scene

        check_scene(scene, file)


def _cmd_plan(args) -> int:
    import dataclasses

    from drake_clutter.common.typed_yaml import to_data
    from drake_clutter.planners.registry import (
        check_planners,
        get_planner,
        named_planners,
        run_planners,
    )
    from drake_clutter.planners.selection import selected_index
    from drake_clutter.scene.scenes import resolve_scene
    from drake_clutter.trajectory import save_plan

    config = _load_config(args)
    scene = resolve_scene(args.scene)
    _check_scene_for_engine(scene, config, args.scene)
    if args.angles is not None:
        if args.angles < 1:
            raise InputError("<command line>", "--angles", f"must be at least 1, got {args.angles}")
        config = dataclasses.replace(
            config, baseline=dataclasses.replace(config.baseline, num_angles=args.angles))
    if not Path(args.out).resolve().parent.is_dir():
        raise InputError("<command line>", "--out", f"no such directory for {args.out}")
    names = named_planners([args.planner])
    check_planners(config, names, args.config or "<command line>")
    plans = run_planners(scene, config, names)
    candidates = [c for name in names for c in plans[name]]
    # The candidate each planner would execute, ranked without the judge; its index among
    # the file's candidates.
    offsets = {name: sum(len(plans[n]) for n in names[:names.index(name)]) for name in names}
    chosen = {name: selected_index(plans[name], config) for name in names}
    selected = {name: None if i is None else offsets[name] + i for name, i in chosen.items()}
    save_plan(args.out, scene.name, candidates,
              extra={"planner": args.planner, "selected": selected,
                     "config": {"baseline": to_data(config.baseline),
                                "physics": to_data(config.physics)}})
    for name in names:
        print(get_planner(name).table(plans[name]))
        i = chosen[name]
        print(f"{name} would execute: " + ("nothing (no usable candidate)" if i is None else
                                          f"alpha {plans[name][i].alpha:+.3f} (candidate "
                                          f"{selected[name]} of the file)"))
    ok = sum(c.ok for c in candidates)
    print(f"{ok} of {len(candidates)} angles ok ({scene.name}, {args.planner}); wrote {args.out}")
    return 0


def _cmd_experiment_rejudge(args) -> int:
    from drake_clutter.experiments.executors import format_summary
    from drake_clutter.experiments.rejudge import rejudge

    if args.workers < 1:
        raise InputError("<command line>", "--workers", f"must be at least 1, got {args.workers}")
    if Path(args.db).resolve() == Path(args.source).resolve():
        raise InputError("<command line>", "--db", "must be another store than the source")
    summary = rejudge(args.source, args.db, args.overrides, args.workers,
                      progress=not args.no_progress, current_judge=args.current_judge)
    print(format_summary(summary))
    if summary["carried"]:
        print(f"{summary['carried']} rows kept their outcome unreplayed: no replay of theirs "
              "is a kinematic failure, and only a force limit was raised")
    return 0


def _cmd_experiment_run(args) -> int:
    from drake_clutter.experiments.executors import format_summary, run_experiment
    from drake_clutter.experiments.specs import load_spec

    spec, spec_file = load_spec(args.spec)
    if args.workers < 1:
        raise InputError("<command line>", "--workers", f"must be at least 1, got {args.workers}")
    summary = run_experiment(spec, spec_file, args.db, args.executor, args.workers, args.address,
                             args.retry_failed, progress=not args.no_progress)
    print(format_summary(summary))
    return 0


def _cmd_experiment_digests(args) -> int:
    import json

    from drake_clutter.experiments.digests import compare_digests, plan_digests, read_digests

    if args.compare:
        if args.tiers:
            raise InputError("<command line>", "--compare", "takes no tier names")
        differ, text = compare_digests(*(read_digests(p) for p in args.compare))
        print(text, end="")
        return 1 if differ else 0
    out = open(args.out, "w", encoding="utf-8") if args.out else sys.stdout
    try:
        for record in plan_digests(args.tiers or ["smoke"]):
            print(json.dumps(record), file=out, flush=True)
    finally:
        if args.out:
            out.close()
    return 0


def _cmd_stores_compare(args) -> int:
    from drake_clutter.experiments.compare import compare_table, load_stores, shared

    print(compare_table(shared(load_stores(args.stores)), args.against), end="")
    return 0


def check_output_folder(path: str | Path, flag: str) -> None:
    """Raises an InputError naming ``flag`` unless ``path`` is, or can be made, a writable
    folder: not a file, not under a file, its nearest existing folder writable."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError("<command line>", flag, f"{path} is a file, not a folder")
    existing = next(p for p in (path, *path.parents) if p.exists())
    if not existing.is_dir():
        raise InputError("<command line>", flag, f"{path} lies under the file {existing}")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError("<command line>", flag, f"{existing} is not writable")


def _cmd_report(args) -> int:
    from drake_clutter.experiments.report import write_report
    from drake_clutter.experiments.store import Store

    config = _load_config(args)
    check_output_folder(args.out, "--out")
    with Store(args.db, read_only=True) as store:
        rows = store.rows()
    configs = list(dict.fromkeys(r["config_name"] for r in rows))
    if args.against is not None and args.against not in configs:
        raise InputError(str(args.db), "--against", f"no configuration "
                         f"{args.against!r} in the store (it has: {', '.join(configs) or 'none'})")
    paths = write_report(rows, args.out, source=str(args.db), config=config.report,
                         reference=args.against)
    print(f"{len(rows)} rows from {args.db}; wrote {', '.join(sorted(paths))} to {args.out}")
    return 0


def _cmd_config_show(args) -> int:
    from drake_clutter.common.config import config_to_data
    from drake_clutter.common.typed_yaml import dump_yaml

    print(dump_yaml(config_to_data(_load_config(args))), end="")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``drake-clutter``."""
    from drake_clutter.planners.registry import ALL_PLANNERS, planner_names
    from drake_clutter.robot.pr2 import VARIANTS

    parser = OneLineParser(prog="drake-clutter", description=__doc__.splitlines()[0])
    groups = parser.add_subparsers(dest="group", required=True, parser_class=OneLineParser)

    scene = groups.add_parser("scene", help="generate, validate, list and show scenes")
    scene_cmds = scene.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    gen = scene_cmds.add_parser("generate", help="generate a random scene (Sec. VI-B)")
    gen.add_argument("--kind", choices=("bookshelf", "fridge"), required=True)
    gen.add_argument("--objects", type=int, required=True, help="boxes, the target included")
    gen.add_argument("--seed", type=int, required=True)
    gen.add_argument("-o", "--output", required=True, help="YAML file to write")
    _add_config_args(gen)
    gen.set_defaults(func=_cmd_scene_generate)

    val = scene_cmds.add_parser("validate", help="check a scene file")
    val.add_argument("file")
    val.set_defaults(func=_cmd_scene_validate)

    lst = scene_cmds.add_parser("list", help="list the shipped scenes")
    lst.set_defaults(func=_cmd_scene_list)

    show = scene_cmds.add_parser("show", help="show a scene and the arm in Meshcat")
    show.add_argument("scene", help="a scene YAML file or a shipped scene name")
    show.add_argument("--html", help="write a self-contained HTML file instead of serving")
    show.add_argument("--variant", choices=VARIANTS, default="capsules",
                      help="arm geometry to draw (default: the planning proxy)")
    show.add_argument("--no-wait", action="store_true",
                      help="publish and exit instead of serving until interrupted")
    _add_config_args(show)
    show.set_defaults(func=_cmd_scene_show)

    ev = groups.add_parser("evaluate", help="replay a plan's candidates in Bullet (Sec. III)")
    ev.add_argument("scene", help="a scene YAML file or a shipped scene name")
    ev.add_argument("plan", help="a plan file (JSON) with the scene's candidates")
    ev.add_argument("--lift", action="store_true",
                    help="also close the gripper and lift the target 5 cm (beyond the paper)")
    ev.add_argument("--out", required=True, help="outcome file (JSON) to write")
    ev.add_argument("--robust", type=int, metavar="K",
                    help="the robust judge: K replays, the first nominal, K - 1 in seeded "
                    "perturbed worlds (default: evaluation.robust_replays)")
    ev.add_argument("--seed", type=int, help="seed of the perturbed worlds (default: "
                    "evaluation.robust_seed)")
    _add_config_args(ev)
    ev.set_defaults(func=_cmd_evaluate)

    plan = groups.add_parser("plan", help="plan approach trajectories for a scene (Sec. IV)")
    plan.add_argument("scene", help="a scene YAML file or a shipped scene name")
    plan.add_argument("--planner", choices=(*planner_names(), ALL_PLANNERS), default="baseline",
                      help="the planner (default: baseline, Sec. IV; physics: Sec. V from the "
                      "baseline's candidates; push: the push search from them; both: baseline and "
                      "push)")
    plan.add_argument("--angles", type=int,
                      help="number of approach angles (default: baseline.num_angles)")
    plan.add_argument("--out", required=True, help="plan file (JSON) to write")
    _add_config_args(plan)
    plan.set_defaults(func=_cmd_plan)

    exp = groups.add_parser("experiment", help="run experiments (Sec. VI-B) into a store")
    exp_cmds = exp.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    run = exp_cmds.add_parser("run", help="run a spec's missing units (resumable)")
    run.add_argument("spec", help="an experiment spec (YAML) or a tier: smoke, small, paper, "
                     "behaviours, probe, probe_half, heldout, candidates")
    run.add_argument("--db", required=True, help="SQLite store to fill (created if absent)")
    run.add_argument("--workers", type=int, default=2, help="processes / Ray CPUs (default 2)")
    run.add_argument("--executor", choices=("local", "ray"), default="local")
    run.add_argument("--address", help="Ray cluster address (default: a local Ray instance)")
    run.add_argument("--retry-failed", action="store_true",
                     help="run again the units whose planner raised or whose worker died")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_experiment_run)
    rej = exp_cmds.add_parser("rejudge", help="replay a store's plans under changed judge "
                              "settings into another store (no planning)")
    rej.add_argument("source", help="the store whose plans to judge again")
    rej.add_argument("--db", required=True, help="SQLite store to fill (created if absent)")
    rej.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    rej.add_argument("--set", dest="overrides", action="append", default=[],
                     metavar="KEY=VALUE", help="a judge setting (evaluation.*), e.g. "
                     "evaluation.robust_replays=8")
    rej.add_argument("--current-judge", action="store_true", help="start from today's "
                     "evaluation defaults instead of the stored ones")
    rej.add_argument("--no-progress", action="store_true", help="no progress bar")
    rej.set_defaults(func=_cmd_experiment_rejudge)
    dig = exp_cmds.add_parser("digests", help="plan tiers and print each plan's digest, or "
                              "compare two digest files (a refactor must not change a plan)")
    dig.add_argument("tiers", nargs="*", help="tier names and/or 'bench' (default: smoke)")
    dig.add_argument("--out", help="JSON-lines file to write (default: standard output)")
    dig.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"),
                     help="two digest files: the plans that differ, seconds new over old")
    dig.set_defaults(func=_cmd_experiment_digests)
    stores = groups.add_parser("stores", help="read experiment stores side by side")
    stores_cmds = stores.add_subparsers(dest="command", required=True,
                                        parser_class=OneLineParser)
    cmp = stores_cmds.add_parser("compare", help="Table III and P(success) per "
                                 "configuration/planner on the initializations all share")
    cmp.add_argument("stores", nargs="+", help="experiment stores (SQLite)")
    cmp.add_argument("--against", required=True, metavar="CONFIGURATION/PLANNER",
                     help="the reference row, e.g. defaults/baseline")
    cmp.set_defaults(func=_cmd_stores_compare)
    rep = groups.add_parser("report", help="Tables III/IV and Fig. 9 from a store")
    rep.add_argument("db", help="an experiment store (SQLite)")
    rep.add_argument("--out", required=True, help="directory for the Markdown, CSV and PNGs")
    rep.add_argument("--against", metavar="CONFIGURATION",
                     help="compare every other configuration with this one per "
                          "initialization (default: the store's first, when it has two)")
    _add_config_args(rep)
    rep.set_defaults(func=_cmd_report)

    cfg = groups.add_parser("config", help="inspect the configuration")
    cfg_cmds = cfg.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    cshow = cfg_cmds.add_parser("show", help="print the effective configuration as YAML")
    _add_config_args(cshow)
    cshow.set_defaults(func=_cmd_config_show)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status (0 ok, 2 bad input)."""
    args = build_parser().parse_args(argv)
    try:
        with interrupt_on_sigterm():
            return args.func(args)
    except InputError as exc:
        print(f"drake-clutter: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except GenerationError as exc:
        print(f"drake-clutter: error: scene generation failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (`processes.Terminated`)
        return 143 if isinstance(exc, Terminated) else 130


if __name__ == "__main__":
    sys.exit(main())
