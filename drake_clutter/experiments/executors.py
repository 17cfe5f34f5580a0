"""Executors: run work units on a local process pool or a Ray cluster, results to a callback.

Both take plain-data units (`specs.WorkUnit.to_data`), a picklable ``work`` function
(default `specs.run_unit`) and ``on_result(unit, result)``, called in the calling
process for each unit as it finishes (the runner commits it to the store there). Every unit
gets exactly one call: a unit whose work raised in a way the worker could not catch, or whose
worker process died, gets `specs.failure_result` (kind ``planner_failure``, error text).

Local (`run_local`): a `concurrent.futures.ProcessPoolExecutor` with the 'spawn' start method
(pydrake is not fork-safe), at most ``workers`` units in flight. A worker that dies (SIGKILL,
out of memory, ``os._exit``) breaks the whole pool, and every unit in flight fails with
BrokenProcessPool without saying whose worker died; so the pool is rebuilt and those units
run again one at a time (the innocent ones finish, the culprit breaks its pool alone and is
recorded as a dead worker).

Ray (`run_ray`): ``ray.init(address=...)`` or a local instance with ``num_cpus=workers``;
each unit is a task (1 CPU) with ``max_retries`` retries when its worker dies. Tasks are
submitted in a bounded window so a 2100-unit study does not flood the scheduler. On a
cluster every node needs drake_clutter installed (same version) in its Python environment.

Worker processes run single-threaded BLAS (OMP/OpenBLAS/MKL threads = 1, as Ray does for its
1-CPU tasks): with one unit per core this avoids oversubscription, and both executors then
compute bit-identical plans. A local worker ends when its parent dies
(`processes.exit_with_parent`), and an interrupted run (Ctrl-C, SIGTERM) ends its workers
before it returns: the units in flight are not stored, and a resumed run plans them.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context

from drake_clutter.common.processes import exit_with_parent, stop_workers
from drake_clutter.experiments.specs import failure_result, run_unit

OnResult = Callable[[dict, dict], None]
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
DEAD_WORKER_REASON = "the worker process died while running this unit"


def single_threaded_environment() -> None:
    """Sets the BLAS thread variables to 1 (unless set) for worker processes started later."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


def run_local(units: Iterable[dict], on_result: OnResult, workers: int,
              work: Callable[[dict], dict] = run_unit) -> None:
    """Runs ``units`` on ``workers`` spawned processes (see the module docstring)."""
    if workers < 1:
        raise ValueError(f"need at least 1 worker, got {workers}")
    single_threaded_environment()
    pending = deque(units)
    suspects: deque[dict] = deque()  # in flight when a pool broke: rerun one at a time
    pool = _new_pool(workers)
    in_flight: dict = {}
    try:
        while pending or suspects or in_flight:
            broken = not _fill(pool, work, pending, suspects, in_flight, workers)
            if not broken:
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    unit, alone = in_flight.pop(future)
                    broken |= _collect(future, unit, alone, suspects, on_result)
            if broken:
                for future, (unit, alone) in list(in_flight.items()):
                    _collect(future, unit, alone, suspects, on_result)
                in_flight.clear()
                pool.shutdown(wait=True, cancel_futures=True)
                pool = _new_pool(workers)
    except BaseException:  # Ctrl-C, SIGTERM (`processes.Terminated`): the units in flight
        stop_workers(pool)  # are abandoned, not waited for; a resumed run plans them
        raise
    pool.shutdown(wait=False, cancel_futures=True)


def _new_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"),
                               initializer=exit_with_parent)


def _fill(pool, work, pending: deque, suspects: deque, in_flight: dict, workers: int) -> bool:
    """Submits units: a suspect only into an empty pool, alone; else up to ``workers``.
    Returns False (the unit back in its queue) when the pool broke while idle."""
    queue, alone, limit = (suspects, True, 1) if suspects else (pending, False, workers)
    while queue and len(in_flight) < limit:
        unit = queue.popleft()
        try:
            in_flight[pool.submit(work, unit)] = (unit, alone)
        except BrokenProcessPool:
            queue.appendleft(unit)
            return False
    return True


def _collect(future, unit: dict, alone: bool, suspects: deque, on_result: OnResult) -> bool:
    """Hands a finished future's result on; returns True when its pool broke. A unit whose
    pool broke is queued as a suspect, or recorded as a dead worker when it ran alone."""
    try:
        result = future.result()
    except BrokenProcessPool:
        if alone:
            on_result(unit, failure_result(DEAD_WORKER_REASON, DEAD_WORKER_REASON))
        else:
            suspects.append(unit)
        return True
    except Exception as exc:  # e.g. an unpicklable result: recorded, the run goes on
        on_result(unit, failure_result(f"the worker failed: {exc!r}", repr(exc)))
        return False
    on_result(unit, result)
    return False


RAY_WINDOW = 4  # ours: tasks in flight per cluster CPU; enough to keep every CPU busy while
# results come back, few enough that the driver never holds thousands of pending tasks


def run_ray(units: Iterable[dict], on_result: OnResult, workers: int | None,
            address: str | None = None, max_retries: int = 2, window: int = RAY_WINDOW,
            work: Callable[[dict], dict] = run_unit) -> None:
    """Runs ``units`` as Ray tasks (see the module docstring). ``workers`` sets the CPUs of a
    local instance (None: all); with ``address`` Ray joins that cluster. At most ``window`` x
    the cluster's CPUs tasks are in flight."""
    import ray
    from ray.exceptions import RayError

    single_threaded_environment()
    started_here = not ray.is_initialized()
    if started_here:
        if address:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    try:
        task = ray.remote(num_cpus=1, max_retries=max_retries)(work)
        limit = max(1, window * int(ray.cluster_resources().get("CPU", 1)))
        pending, in_flight = deque(units), {}
        while pending or in_flight:
            while pending and len(in_flight) < limit:
                unit = pending.popleft()
                in_flight[task.remote(unit)] = unit
            ready, _ = ray.wait(list(in_flight), num_returns=1)
            for ref in ready:
                unit = in_flight.pop(ref)
                try:
                    result = ray.get(ref)
                except RayError as exc:  # a worker died more than max_retries times, etc.
                    text = f"ray: {type(exc).__name__}: {str(exc).splitlines()[0][:300]}"
                    result = failure_result(text, str(exc)[-4000:])
                on_result(unit, result)
    finally:
        if started_here:
            ray.shutdown()


# ----------------------------------------------------------------------------- the runner


def run_experiment(spec, spec_file: str, db_path, executor: str = "local", workers: int = 2,
                   address: str | None = None, retry_failed: bool = False,
                   progress: bool = True, work: Callable[[dict], dict] = run_unit) -> dict:
    """Runs a spec's units that ``db_path`` does not hold yet, committing each result as it
    arrives, with a tqdm bar (ETA) on stderr. Returns the summary (see `format_summary`)."""
    import time

    from drake_clutter.common.config import config_to_data
    from drake_clutter.experiments.specs import check_scenes, expand, resolve_config
    from drake_clutter.experiments.store import Store

    started = time.perf_counter()
    units = expand(spec, spec_file)
    check_scenes(spec, spec_file)
    with Store(db_path) as store:
        store.claim()
        for unit in {u.config_name: u for u in units}.values():
            config = resolve_config(spec, unit.config_name, spec_file)
            store.add_configuration(unit.config_hash, unit.config_name, unit.overrides,
                                    config_to_data(config))
        done = store.done_keys(retry_failed)
        todo = [u.to_data() for u in units if u.key not in done]
        run_id = store.start_run(spec.name, spec_file, executor, workers, len(units),
                                 len(units) - len(todo))
        writer = StoreWriter(store, len(todo), spec.name, progress)
        try:
            if executor == "ray":
                run_ray(todo, writer, workers, address, spec.ray_max_retries, work=work)
            else:
                run_local(todo, writer, workers, work=work)
        finally:
            writer.close()
        store.finish_run(run_id)
    return writer.summary(spec.name, len(units), len(units) - len(todo),
                          time.perf_counter() - started, executor)


class StoreWriter:
    """The ``on_result`` of a run: commits each arriving result to the store and counts the
    outcome kinds (errors apart), overall and per planner, with a tqdm bar (ETA) on stderr."""

    def __init__(self, store, total: int, name: str, progress: bool):
        from tqdm import tqdm

        self.store = store
        self.counts: dict[str, int] = {}
        self.by_planner: dict[str, dict[str, int]] = {}
        self.bar = tqdm(total=total, desc=name, unit="unit", disable=not progress,
                        dynamic_ncols=True)

    def __call__(self, unit: dict, result: dict) -> None:
        self.store.put(unit, result)
        key = "error" if result["error"] else result["outcome"]["kind"]
        self.counts[key] = self.counts.get(key, 0) + 1
        mine = self.by_planner.setdefault(unit["planner"], {})
        mine[key] = mine.get(key, 0) + 1
        self.bar.set_postfix_str(" ".join(f"{k}={v}" for k, v in sorted(self.counts.items())),
                                 refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        """Closes the progress bar."""
        self.bar.close()

    def summary(self, name: str, units: int, skipped: int, elapsed: float,
                executor: str) -> dict:
        """The run's summary (see `format_summary`); ``elapsed`` in s."""
        return {"spec": name, "units": units, "skipped": skipped,
                "ran": sum(self.counts.values()), "counts": self.counts,
                "by_planner": self.by_planner, "elapsed": elapsed, "executor": executor}


def format_summary(summary: dict) -> str:
    """One paragraph: units run and skipped, counts per outcome kind, errors, elapsed time."""
    counts = summary["counts"]
    kinds = "; ".join(f"{planner}: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())
                                                 if k != "error")
                      for planner, c in sorted(summary["by_planner"].items())) or "none"
    return (f"{summary['spec']}: {summary['ran']} units run, {summary['skipped']} already in "
            f"the store (of {summary['units']}); outcomes: {kinds}; errors (exceptions or "
            f"dead workers): {counts.get('error', 0)}; {summary['elapsed']:.1f} s "
            f"({summary['executor']})")
