#!/usr/bin/env python3
"""A PNG of an exported replay page, rendered by headless Chromium: the README's picture.

    python apps/plan_scene.py --html out/main_job.html      # the main job, as static HTML
    python apps/screenshot.py out/main_job.html docs/main_job.png --size 1200x600

Needs Debian's ``chromium`` (``apt-get install chromium``). Bad input (a missing HTML file or
output folder, a malformed size, no chromium) prints one line and exits 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

from drake_clutter.common.arguments import OneLineParser
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.viz.screenshot import BUDGET_MS, ChromiumMissing, screenshot


def _size(text: str) -> tuple[int, int]:
    width, sep, height = text.partition("x")
    if not (sep and width.isdigit() and height.isdigit() and int(width) > 0 and int(height) > 0):
        raise InputError("<command line>", "--size", f"must be WIDTHxHEIGHT in px, got {text!r}")
    return int(width), int(height)


def main(argv=None) -> int:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("html", help="a static HTML page written by --html")
    parser.add_argument("png", help="the picture to write")
    parser.add_argument("--size", default="1200x600", help="window WIDTHxHEIGHT in px")
    parser.add_argument("--budget-ms", type=int, default=BUDGET_MS,
                        help="virtual time to load and draw the page, ms")
    args = parser.parse_args(argv)
    try:
        size = _size(args.size)
        if not Path(args.html).is_file():
            raise InputError(args.html, "html", "no such file")
        if not Path(args.png).resolve().parent.is_dir():
            raise InputError(args.png, "png", "its folder does not exist")
        if args.budget_ms < 1:
            raise InputError("<command line>", "--budget-ms", "must be at least 1")
        print(f"wrote {screenshot(Path(args.html), Path(args.png), size, args.budget_ms)}")
    except ChromiumMissing as exc:
        print(f"screenshot: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except InputError as exc:
        print(f"screenshot: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except RuntimeError as exc:
        print(f"screenshot: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
