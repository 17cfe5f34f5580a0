"""The push planner (beyond the paper): paths bent through via-points so the arm can move boxes
out of its way (``family``), scored by the judge in phi.

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``solvers``, ``phi``.
"""
