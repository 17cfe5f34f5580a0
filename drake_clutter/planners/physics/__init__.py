"""The physics planner of Sec. V: the pipeline (pre-processing, sphere and full phi stages,
post-processing), a phi stage as an iLQR problem, its objectives, the arm's proxy geometry,
and Table I's cost terms on arrays.

May import: as ``planners``.
"""
