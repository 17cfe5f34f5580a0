"""Spawned worker processes that evaluate groups of phi's Jacobian columns in parallel
(`derivatives.PhiDynamics` with ``dynamics.workers`` > 0). Each worker builds a `Phi` (and its
`AutoDiffPhi`) once per spec and keeps the last few; tasks carry only the spec and numpy arrays.
"""

from __future__ import annotations

import multiprocessing
from collections import OrderedDict

from drake_clutter.derivative_groups import group_autodiff, group_differences
from drake_clutter.derivatives_autodiff import AutoDiffPhi
from drake_clutter.dynamics import Phi, PhiSpec

_WORKER_PHIS: OrderedDict = OrderedDict()  # in each worker process: spec key -> [Phi,
# AutoDiffPhi or None (built on first use)]
_WORKER_CACHE_SIZE = 4


def _worker_phi(key: str, spec: PhiSpec, autodiff: bool = False):
    """This worker's Phi of ``spec`` (or its AutoDiffPhi), built once."""
    entry = _WORKER_PHIS.get(key)
    if entry is None:
        entry = _WORKER_PHIS[key] = [Phi(spec), None]
        while len(_WORKER_PHIS) > _WORKER_CACHE_SIZE:
            _WORKER_PHIS.popitem(last=False)
    _WORKER_PHIS.move_to_end(key)
    if autodiff and entry[1] is None:
        entry[1] = AutoDiffPhi(entry[0])
    return entry[1] if autodiff else entry[0]


def _run_task(task):
    """Worker entry point: ('trace', key, spec, x, u), ('groups', key, spec, x, u, nominal,
    groups, step, scheme), ('autodiff', key, spec, x, u, groups) or ('call', key, spec,
    function, args): function(this worker's Phi of spec, *args), a module-level function."""
    kind, key, spec, *args = task
    if kind == "autodiff":
        return group_autodiff(_worker_phi(key, spec, autodiff=True), *args)
    phi = _worker_phi(key, spec)
    if kind == "trace":
        return phi.step_full(*args)
    if kind == "call":
        function, call_args = args
        return function(phi, *call_args)
    return group_differences(phi, *args)


class WorkerPool:
    """Spawned worker processes for phi evaluations; each builds a Phi once per spec.

    'spawn' (not fork): pydrake objects are not fork-safe. Start-up (Python + pydrake import)
    takes a second or two per worker and happens on first use; reuse one pool across specs.
    """

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError(f"a worker pool needs at least 1 worker, got {workers}")
        self.workers = workers
        self._pool = None

    def _started(self):
        if self._pool is None:
            self._pool = multiprocessing.get_context("spawn").Pool(self.workers)
        return self._pool

    def map(self, tasks: list) -> list:
        """Runs tasks (see `_run_task`) in the workers, results in task order."""
        return self._started().map(_run_task, tasks, chunksize=1)

    def warm_up(self, spec: PhiSpec) -> None:
        """Starts the workers and has them build ``spec``'s Phi (a timing convenience: a
        worker that takes none of these tasks builds it on first use)."""
        self._started().map(_build_only, [(spec.key, spec)] * (2 * self.workers), chunksize=1)

    def close(self) -> None:
        """Stops the workers."""
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _build_only(args) -> bool:
    _worker_phi(*args)
    return True
