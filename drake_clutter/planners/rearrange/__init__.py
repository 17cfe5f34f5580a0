"""The rearrange planner (beyond the paper): the boxes that crowd the final reach are pushed
aside first, then the reach. The board model and the region to clear (``board``), a push as a
joint path (``actions``), the beam search over which box goes where in what order
(``search``), the planner judged in phi (``planner``) and its record (``record``).

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``solvers``, ``phi``.
"""
