"""The push planner (beyond the paper): paths bent through via-points so the arm can move boxes
out of its way (``family``, aimed at the boxes met: ``aim``), a sampling search over them
(``search``) scored by the judge in phi, and the planner (``planner``).

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``solvers``, ``phi``.
"""
