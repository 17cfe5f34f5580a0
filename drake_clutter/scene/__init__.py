"""Scenes: the Scene/Shelf/BoxObject description and its YAML files, the shipped scenes
(``shipped/``), the shelf geometry and its SDF, and the random generators of Sec. VI-B.

May import: ``common``, ``robot``.
"""
