"""The contact conformance suite: engine-neutral scripted pushes (single pushes, chains, edges,
squeezes, a topple, drag tests) run in phi's own Drake world, in a Bullet world with the judge's
engine settings and in MuJoCo (the reference engine, optional: ``pip install mujoco``), with
quasi-static mechanics' prediction beside them.

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``, ``phi``.
"""
