"""phi, the smooth-contact dynamics of Sec. V: one step and rollouts of the boxes pushed by a
kinematic arm, the pruning of boxes the path cannot reach, and the derivatives A_t, B_t
(coloured finite differences in worker processes, or seeded AutoDiffXd).

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``.
"""
