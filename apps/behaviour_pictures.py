#!/usr/bin/env python3
"""Pictures of what a planner does on a store's scenes: per scene, a strip of frames of its
plan and the baseline's, replayed in Bullet side by side (Sec. VI-A's figures).

    drake-clutter experiment run behaviours --db behaviours.db --workers 2
    python apps/behaviour_pictures.py behaviours.db --out docs/behaviours

Per scene of the store, the initialization shown is the one where the planner's robust
P(success) exceeds the baseline's the most (`experiments.paired.widest_wins`). Its two stored
plans are replayed once more in Bullet (the nominal replay, recorded) and drawn as
`viz.pictures.frame_strip` draws them: ``--frames`` instants from the start to the end, the
planner's copy on the right. One PNG per scene, ``<out>/<scene>.png``; a line per picture names
the angle, the planner's path and both robust P(success).
Needs Debian's ``chromium``. Bad input prints one line and exits 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from drake_clutter.common.arguments import OneLineParser
from drake_clutter.common.config import Config, config_from_data, load_config, upgrade_stored
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.planners.registry import get_planner


def picture(row_pair: tuple[dict, dict], config: Config, out: Path, frames: int) -> str:
    """Replays the pair, writes ``<out>/<scene>.png``, returns the line to print."""
    from drake_clutter.evaluation.judge import evaluate_candidates
    from drake_clutter.experiments.specs import stored_scene
    from drake_clutter.trajectory import Candidate
    from drake_clutter.viz.pictures import frame_strip
    from drake_clutter.viz.replay import PlanView

    base, row = row_pair
    scene = stored_scene(row["scene"], config)
    views = []
    for stored in (row, base):
        candidate = Candidate.from_data(stored["plan"])
        (outcome,) = evaluate_candidates(scene, [candidate], config.evaluation,
                                         record_fps=config.viz.fps)
        views.append(PlanView(stored["planner"], candidate, outcome))
    label = get_planner(row["planner"]).record(row["plan"].get("details") or {}).label
    title = (f"{scene.name}, alpha {row['alpha']:+.3f}: {row['planner']} {label} "
             f"(robust P(success) {row['p_success']:.2f} against {base['p_success']:.2f})")
    png = frame_strip(scene, views, config, out / f"{scene.name}.png", frames, title)
    return f"wrote {png}: {title}"


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("db", help="an experiment store with the baseline and the planner")
    parser.add_argument("--out", required=True, help="folder for the PNGs")
    parser.add_argument("--planner", default="push", help="the planner shown beside the "
                        "baseline (default: push)")
    parser.add_argument("--frames", type=int, default=4, help="instants per picture (default 4)")
    parser.add_argument("--scene", action="append", default=[],
                        help="only this scene (repeatable; default: every scene of the store)")
    parser.add_argument("--config", help="YAML overrides of the viz settings (the camera)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    return parser


def main(argv=None) -> int:
    from drake_clutter.experiments.paired import widest_wins
    from drake_clutter.experiments.store import Store, StoreError

    args = _parser().parse_args(argv)
    try:
        if args.frames < 1:
            raise InputError("<command line>", "--frames", f"must be at least 1, got {args.frames}")
        if not Path(args.out).is_dir():
            raise InputError(args.out, "--out", "no such directory")
        if not Path(args.db).is_file():
            raise InputError(args.db, "db", "no such file")
        overrides = load_config(args.config, args.overrides)
        with Store(args.db, read_only=True) as store:
            rows, configurations = store.rows(), store.configurations()
        chosen = widest_wins(rows, args.planner)
        if args.scene:
            missing = sorted(set(args.scene) - set(chosen))
            if missing:
                raise InputError(args.db, "--scene", f"no judged {args.planner}/baseline pair "
                                 f"for {', '.join(missing)}")
            chosen = {s: chosen[s] for s in args.scene}
        if not chosen:
            raise InputError(args.db, "planner", f"no judged {args.planner}/baseline pair")
        for pair in chosen.values():
            stored = config_from_data(
                upgrade_stored(configurations[pair[1]["config_hash"]]["config"]))
            config = dataclasses.replace(stored, viz=overrides.viz)
            print(picture(pair, config, Path(args.out), args.frames), flush=True)
    except (InputError, StoreError) as exc:
        print(f"behaviour_pictures: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    sys.exit(main())
