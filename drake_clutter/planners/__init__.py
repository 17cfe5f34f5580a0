"""The planners: approach angles and end poses, shelf clearance, the baseline (Sec. IV),
the physics planner (``physics/``, Sec. V), and the registry every caller picks a planner
from (``registry``).

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``solvers``, ``phi``.
"""
