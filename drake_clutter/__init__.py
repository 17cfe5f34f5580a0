"""drake_clutter: physics-based trajectory optimisation for grasping in clutter (Kitaev et al.,
ICRA 2015) on Drake, with the paper's baseline and its Bullet judge.

The rooms, in the order data flows and imports point (each may import only those above it;
``tests/test_layout.py`` keeps it so):

- ``common``: typed YAML and the one configuration;
- ``robot``: the PR2 arm model;
- ``scene``: scenes, shipped scenes, shelves, random generators (Sec. VI-B);
- ``trajectory``: trajectories, planner candidates, plan files;
- ``worlds``: the Drake planning and dynamics worlds, the Bullet world;
- ``solvers``: iLQR (pure NumPy);
- ``phi``: the smooth-contact dynamics and its derivatives (Sec. V);
- ``planners``: the baseline (Sec. IV), the physics planner (Sec. V), the push planner, the
  parts they share, the registry;
- ``evaluation``: the judge (Sec. III), which never sees a planner;
- ``experiments``: specs, tiers, store, executors, reports (Sec. VI-B);
- ``viz``: Meshcat views and replays, cost curves; ``conformance``: phi's contact conformance
  suite against MuJoCo and Bullet;
- ``cli``: the ``drake-clutter`` command; ``testing``: helpers shared by tests and benchmarks.
"""
