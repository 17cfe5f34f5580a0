"""Experiment specs that tests share: a tiny one that plans in seconds."""

from __future__ import annotations

# One generated bookshelf scene with its target alone, two approach angles, the baseline only.
TINY_SPEC = """
name: tiny
planners: [baseline]
generated:
  - {kind: bookshelf, levels: [1], seeds: [2015]}
angles: [4, 9]
overrides: [dynamics.workers=0]
"""
