"""The outer loop the planners that refine the baseline's candidates share (the physics planner
of Sec. V and the push planner): check the configuration, build the scene's planning worlds
once (`context.PlanningContext`), start the worker pool phi's rollouts run in
(``dynamics.workers``; 0: none, in this process), make one call per candidate, close the pool.

The first candidate's budget also pays for the planning worlds: its clock starts before they
are built. Each returned candidate carries its start's angle index (`starts.angle_index`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drake_clutter.common.config import Config, check_config
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.starts import angle_index
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate

# refine(context, start candidate, its angle index, pool or None, the monotonic time its
# budget counts from or None for now) -> the refined candidate
Refine = Callable[[PlanningContext, Candidate, int, "WorkerPool | None", "float | None"],
                  Candidate]


def refine_each(scene: Scene, config: Config, start: list[Candidate], refine: Refine
                ) -> list[Candidate]:
    """``refine`` on each of the baseline's candidates ``start``, in order (module docstring);
    a nonsensical configuration raises ConfigError before anything is built."""
    started = time.monotonic()
    check_config(config)
    context = PlanningContext(scene, config)
    pool = WorkerPool(config.dynamics.workers) if config.dynamics.workers > 0 else None
    out = []
    try:
        if pool is not None:
            pool.start()  # the workers start up while the first candidate's worlds are built
        for candidate in start:
            index = angle_index(candidate, config)
            refined = refine(context, candidate, index, pool, started)
            refined.index = index
            out.append(refined)
            started = None
    finally:
        if pool is not None:
            pool.close()
    return out
