"""The contact conformance suite: does phi push like the world?

    python benchmarks/bench_contact.py [--grid FILE] [--families single,chain,...]
        [--engines phi,bullet,mujoco_default,mujoco_stiff] [--set FIELD=VALUE ...]
        [--config FILE] [--json FILE] [--cases FILE] [--judge]

Engine-neutral scripted scenarios (`drake_clutter.conformance.scenarios`: single pushes,
chains, edges, squeezes, a topple, drags) run in phi's own Drake world (under the configuration
given with ``--config`` / ``--set``: ``world.*``, ``dynamics.*``, ``baseline.knot_time``), in
Bullet with the judge's engine settings (``evaluation.*``) and in MuJoCo (the reference,
default and stiff), with quasi-static mechanics' prediction beside them. Printed: agreement of
the boxes' classes with MuJoCo per family and engine, the single pushes against mechanics
(all, and those more than 15 % from the tipping threshold), thrown boxes, the cases phi's
jam measure reads as jams (`phi.jam`, ``phi_judge.jam_depth``), squeeze forces and phi's jam
measure of each squeeze, realised drag friction and rise, and seconds per case. ``--json``
writes the summary, ``--cases`` one row per case (JSON). ``--grid`` replaces the single-push
grid (YAML, schema in docs/phi.md). ``--judge`` runs phi as the judge in phi does
(`phi_judge.judge_dynamics`: its engine, time step, readings and sleeping boxes). Bad input
(a grid, a configuration, a friction pair an engine cannot realise, MuJoCo missing) is one
line on stderr, exit status 2, nothing written.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from tqdm import tqdm

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.conformance.friction import (
    UnrealisableFriction,
    bullet_coefficients,
    drake_coefficients,
)
from drake_clutter.conformance.scenarios import FAMILIES, SingleGrid, default_scenarios, load_grid
from drake_clutter.conformance.suite import (
    ENGINES,
    REFERENCE,
    MissingMujoco,
    case_rows,
    mujoco_engine,
    run_cases,
    summarise,
)
from drake_clutter.planners.phi_judge import judge_dynamics


def _names(text: str, known: tuple[str, ...], what: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise InputError("<command line>", f"--{what}",
                         f"unknown {what[:-1]} {unknown[0] if unknown else '(none given)'!r} "
                         f"(known: {', '.join(known)})")
    return names


def _check_inputs(args) -> tuple:
    """Everything the run needs, checked before anything runs (InputError / MissingMujoco)."""
    config = load_config(args.config, args.set)
    grid = load_grid(args.grid) if args.grid else SingleGrid()
    families = _names(args.families, FAMILIES, "families")
    engines = _names(args.engines, ENGINES, "engines")
    scenarios = default_scenarios(grid, families)
    for scenario in scenarios:
        try:
            drake_coefficients(scenario)
            bullet_coefficients(scenario)
        except UnrealisableFriction as error:
            raise InputError(args.grid or "<default grid>", scenario.name, str(error)) from None
    if any(e.startswith("mujoco") for e in engines):
        mujoco_engine()
    return config, scenarios, engines


def _print_family(name: str, summary: dict, engines) -> None:
    print(f"\n{name}: {summary['cases']} cases")
    for engine in engines:
        parts = []
        if f"{engine}_agrees_with_mujoco" in summary:
            parts.append(f"classes agree with MuJoCo {summary[f'{engine}_agrees_with_mujoco']}"
                         f"/{summary['cases']}")
        if f"{engine}_agrees_with_mujoco_far_from_threshold" in summary:
            parts.append(f"far from the threshold "
                         f"{summary[f'{engine}_agrees_with_mujoco_far_from_threshold']}"
                         f"/{summary['far_from_threshold']}")
        if f"{engine}_tips_where_mechanics_slides" in summary:
            parts.append(f"tips where mechanics slides "
                         f"{summary[f'{engine}_tips_where_mechanics_slides']}"
                         f"/{summary['mechanics_slides']}, slides where it tips "
                         f"{summary[f'{engine}_slides_where_mechanics_tips']}")
        parts.append(f"thrown {summary[f'{engine}_thrown']}")
        if engine == "phi" and "phi_jams" in summary:
            parts.append(f"read as jams {summary['phi_jams']}")
        if summary[f"{engine}_failed"]:
            parts.append(f"failed {summary[f'{engine}_failed']}")
        print(f"  {engine:15} " + ", ".join(parts))


def report(summary: dict, engines) -> None:
    """Prints the summary's tables."""
    for family in ("single", "chain", "edge", "topple"):
        if family in summary:
            _print_family(family, summary[family], engines)
    if "squeeze" in summary:
        print("\nsqueeze: the box's force on the static shelf beyond its weight (N), "
              "last 0.2 s")
        for row in summary["squeeze"]:
            jam = (f"  phi's jam measure {row['phi_jam_mm']:.2f} mm"
                   f"{' (a jam)' if row['phi_reads_jam'] else ''}" if "phi_jam_mm" in row else "")
            print(f"  {row['depth_mm']:3.0f} mm " + "  ".join(
                f"{e} {row[f'{e}_force_N']:9.2f}" for e in engines) + jam)
    if "drag" in summary:
        print("\ndrag: realised box-board friction (deceleration / g) and the rise of the sliding "
              "box (mm)")
        for row in summary["drag"]:
            print(f"  v0 {row['speed']:.1f} m/s pair {row['pair']:.2f}: " + "  ".join(
                f"{e} {row[f'{e}_realised']:.3f} / {row[f'{e}_rise_m'] * 1000:5.1f}"
                for e in engines))
    print("\nseconds per case: " + ", ".join(
        f"{e} {s:.3f}" for e, s in summary["seconds_per_case"].items()))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grid", type=Path, help="single-push grid (YAML)")
    parser.add_argument("--families", default=",".join(FAMILIES))
    parser.add_argument("--engines", default=",".join(ENGINES))
    parser.add_argument("--config", type=Path, help="configuration YAML for phi and the judge")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    parser.add_argument("--json", type=Path, help="write the summary here")
    parser.add_argument("--cases", type=Path, help="write one row per case here (JSON)")
    parser.add_argument("--judge", action="store_true",
                        help="phi as the judge in phi runs it (phi_judge's engine, time step, "
                        "readings and sleep: planners.phi_judge.judge_dynamics)")
    args = parser.parse_args(argv)
    try:
        config, scenarios, engines = _check_inputs(args)
    except (InputError, MissingMujoco) as error:
        print(f"bench_contact: {error}", file=sys.stderr)
        return EXIT_USAGE
    if args.judge:
        config = replace(config, dynamics=judge_dynamics(config))
    if REFERENCE not in engines:
        print(f"(no {REFERENCE}: agreement columns are left out)")
    with tqdm(total=len(scenarios), desc="cases", file=sys.stderr) as bar:
        results = run_cases(scenarios, config, engines, progress=bar.update)
    summary = summarise(results, engines)
    report(summary, engines)
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    if args.cases:
        args.cases.write_text(json.dumps(case_rows(results, engines), indent=1) + "\n",
                              encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
