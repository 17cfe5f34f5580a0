"""Scenes: the Scene/Shelf/BoxObject description and its YAML files, the shipped scenes
(``shipped/``), the shelf geometry and its SDF, the random generators of Sec. VI-B, and the
quasi-static mechanics of a pushed box (``mechanics``).

May import: ``common``, ``robot``.
"""
