"""The planners, one module or folder per algorithm behind the `registry.Planner` protocol:
the baseline (``baseline``, Sec. IV), the physics planner (``physics/``, Sec. V) and the push
planner (``push/``, beyond the paper). The parts they share have one home each: approach angles
and end poses (``approach``), shelf clearance (``clearance``), the arm's planning geometry and
its box checks (``geometry``), a scene's planning worlds built once (``context``), the straight
starts at several grasp heights (``starts``), phi's ensemble members (``members``), the judge in
phi (``phi_judge``), the outer loop of the planners that refine the baseline's candidates
(``loop``), the choice of the plan to execute (``selection``) and the registry. No algorithm
imports another's internals, and nothing outside a planner's module or folder reads its
candidates' ``details``: each planner reads its own (``Planner.record``, ``Planner.score``).

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``solvers``, ``phi``.
"""
