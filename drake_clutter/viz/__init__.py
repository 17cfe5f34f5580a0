"""Drawing: Meshcat views of scenes, side-by-side replays of judged plans, static HTML and
cost-term curves.

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``evaluation``.
"""
