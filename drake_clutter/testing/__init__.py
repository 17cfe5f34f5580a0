"""Helpers that tests and benchmarks share (fixture scenes, scripted arm paths). Not used
by the library itself.

May import: anything but ``cli``.
"""
