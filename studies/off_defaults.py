#!/usr/bin/env python3
"""The code that runs only off the defaults: statements of ``drake_clutter/planners``, ``phi``
and ``solvers`` that the baseline, the push planner and the physics planner never execute when
they plan with the default configuration (coverage.py; ``dynamics.workers=0`` so the judge in
phi runs in this process). What is left is code behind settings off by default, and error paths.

    python studies/off_defaults.py                  # default_fridge and bookshelf_n10_s0
    python studies/off_defaults.py --angles 3 7 10 --show

Prints the statements, those never run and their share, per module with ``--show``.

Its dated results: docs/log/layout.md.
"""

from __future__ import annotations

import argparse
import io
import sys


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--angles", type=int, nargs="+", default=[3, 7, 10])
    parser.add_argument("--show", action="store_true", help="the per-module table too")
    args = parser.parse_args(argv)
    try:
        import coverage
    except ImportError:
        print("studies/off_defaults.py: coverage is not installed (pip install coverage)",
              file=sys.stderr)
        return 2
    cov = coverage.Coverage(source=["drake_clutter.planners", "drake_clutter.phi",
                                    "drake_clutter.solvers"], data_file=None)
    cov.start()
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.registry import run_planners
    from drake_clutter.scene.generators import generate_scene
    from drake_clutter.scene.scenes import load_shipped_scene

    config = load_config(None, ["dynamics.workers=0"])
    for scene in (load_shipped_scene("default_fridge"),
                  generate_scene("bookshelf", 10, 0, config.generator)):
        for angle in args.angles:
            run_planners(scene, config, ["baseline", "push", "physics"], angles=[angle])
    cov.stop()
    out = io.StringIO()
    cov.report(file=out)
    rows = [line.split() for line in out.getvalue().splitlines()]
    rows = [r for r in rows if len(r) == 4 and r[1].isdigit() and r[0] != "TOTAL"]
    statements = sum(int(r[1]) for r in rows)
    missed = sum(int(r[2]) for r in rows)
    if args.show:
        print(out.getvalue())
    share = 100 * missed / max(statements, 1)
    print(f"statements {statements}, never run {missed} ({share:.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
