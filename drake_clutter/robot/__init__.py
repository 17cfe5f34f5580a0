"""The PR2 arm: its kinematic description (one place), joint limits, velocity limits, the
gripper, and the generated URDF geometry variants in ``models/urdf``.

May import: ``common``.
"""
