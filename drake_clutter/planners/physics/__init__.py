"""The physics planner of Sec. V: the pipeline (pre-processing, sphere and full phi stages,
post-processing), the start's grasp height, a phi stage as an iLQR problem, its objectives and
Table I's cost terms on arrays.

May import: as ``planners``.
"""
