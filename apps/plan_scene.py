#!/usr/bin/env python3
"""The main job: one scene in Meshcat (the planners join as they land).

    python apps/plan_scene.py                         # the default shipped scene, served live
    python apps/plan_scene.py --scene fig7_cascade    # a shipped scene by name, or a YAML file
    python apps/plan_scene.py --html out.html         # write a self-contained HTML file instead

Prints the Meshcat URL and serves until Ctrl-C unless --html is given. Bad input prints one
line and exits 2.
"""

from __future__ import annotations

import argparse
import sys

from drake_clutter.cli import EXIT_USAGE
from drake_clutter.config import load_config
from drake_clutter.robot_model import VARIANTS
from drake_clutter.scenes import DEFAULT_SCENE, resolve_scene
from drake_clutter.typed_yaml import InputError


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=DEFAULT_SCENE,
                        help=f"shipped scene name or YAML file (default: {DEFAULT_SCENE})")
    parser.add_argument("--html", help="write a self-contained HTML file instead of serving")
    parser.add_argument("--variant", choices=VARIANTS, default="capsules")
    parser.add_argument("--no-browser", action="store_true",
                        help="publish once and exit instead of serving until interrupted")
    parser.add_argument("--config", help="YAML configuration overrides")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    try:
        from drake_clutter.viz import show_scene

        config = load_config(args.config, args.overrides)
        scene = resolve_scene(args.scene)
        show_scene(scene, config, variant=args.variant, html=args.html,
                   wait=not args.html and not args.no_browser)
    except InputError as exc:
        print(f"plan_scene: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    sys.exit(main())
