"""Spawned worker processes that evaluate groups of phi's Jacobian columns in parallel
(`derivatives.PhiDynamics` with ``dynamics.workers`` > 0). Each worker builds a `Phi` (and its
`AutoDiffPhi`) once per spec and keeps the last few; tasks carry only the spec and numpy arrays.
"""

from __future__ import annotations

import multiprocessing
from collections import OrderedDict
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from drake_clutter.common.processes import exit_with_parent, stop_workers
from drake_clutter.phi.autodiff import AutoDiffPhi
from drake_clutter.phi.colouring import group_autodiff, group_differences
from drake_clutter.phi.dynamics import PhiSpec
from drake_clutter.phi.engines import build_phi

_WORKER_PHIS: OrderedDict = OrderedDict()  # in each worker process: spec key -> [Phi,
# AutoDiffPhi or None (built on first use)]
_WORKER_CACHE_SIZE = 4


def _worker_phi(key: str, spec: PhiSpec, autodiff: bool = False):
    """This worker's Phi of ``spec`` (or its AutoDiffPhi), built once."""
    entry = _WORKER_PHIS.get(key)
    if entry is None:
        entry = _WORKER_PHIS[key] = [build_phi(spec), None]
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


class WorkerDied(RuntimeError):
    """A worker process ended abruptly (killed, out of memory, a crash inside Drake)."""


class WorkerPool:
    """Spawned worker processes for phi evaluations; each builds a Phi once per spec.

    'spawn' (not fork): pydrake objects are not fork-safe. Start-up (Python + pydrake import)
    takes a second or two per worker and happens on first use; reuse one pool across specs.
    A worker that dies mid-task raises `WorkerDied` (a RuntimeError: the physics planner
    records the candidate as failed) instead of waiting forever, and the next call starts
    fresh workers. A worker ends when its parent process dies (`processes.exit_with_parent`).
    """

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError(f"a worker pool needs at least 1 worker, got {workers}")
        self.workers = workers
        self._pool = None

    def _started(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.workers,
                                             mp_context=multiprocessing.get_context("spawn"),
                                             initializer=exit_with_parent)
        return self._pool

    def run(self, function, items: list) -> list:
        """function(item) for every item in the workers (a picklable module-level function),
        results in order."""
        try:
            return list(self._started().map(function, items, chunksize=1))
        except BrokenProcessPool as exc:
            self.close()
            raise WorkerDied(f"a phi worker process died ({exc}); the pool is restarted on "
                             "its next use") from exc

    def map(self, tasks: list) -> list:
        """Runs tasks (see `_run_task`) in the workers, results in task order."""
        return self.run(_run_task, tasks)

    def start(self) -> None:
        """Starts the workers without waiting for them: each imports its modules while the
        caller goes on (its first `run` then finds them ready)."""
        pool = self._started()
        for _ in range(self.workers):
            pool.submit(_ready)

    def warm_up(self, spec: PhiSpec) -> None:
        """Starts the workers and has them build ``spec``'s Phi (a timing convenience: a
        worker that takes none of these tasks builds it on first use)."""
        self.run(_build_only, [(spec.key, spec)] * (2 * self.workers))

    def close(self) -> None:
        """Stops the workers now: every result asked for has been read by then, and a worker
        still starting up (`start`) is not waited for."""
        if self._pool is not None:
            stop_workers(self._pool)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _ready() -> bool:
    return True


def _build_only(args) -> bool:
    _worker_phi(*args)
    return True
