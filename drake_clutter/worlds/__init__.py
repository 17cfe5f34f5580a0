"""Simulated worlds of a scene: the Drake planning world (kinematics, IK, distances), the
Drake dynamics world phi's plant is built on (SAP, hydroelastic boxes, PD-servoed arm), and
the pybullet world the judge replays plans in.

May import: ``common``, ``robot``, ``scene``, ``trajectory``.
"""
