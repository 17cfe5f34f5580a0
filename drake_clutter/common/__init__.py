"""Shared foundations: typed YAML (frozen dataclasses from YAML, errors naming file, field
and reason) and the one typed configuration of the whole project.

May import: nothing of drake_clutter (only the standard library, NumPy and PyYAML).
"""
