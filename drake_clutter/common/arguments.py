"""The command line's argument parser, shared by ``drake-clutter`` and the apps."""

from __future__ import annotations

import argparse
import sys

from drake_clutter.common.typed_yaml import EXIT_USAGE


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line on stderr and exits 2."""

    def error(self, message: str):  # noqa: D102 - argparse API
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)
