"""The judge of Sec. III: a plan replayed with hard contacts in Bullet and sorted into
outcome classes, the lift check, and the recordings replays are drawn from. It sees a
Scene and a Trajectory, never a planner.

May import: ``common``, ``robot``, ``scene``, ``trajectory``, ``worlds``.
"""
