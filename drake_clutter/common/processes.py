"""Worker processes that never outlive their parent, and SIGTERM read as an interrupt.

A pool's worker whose parent is killed (SIGKILL, the machine's out-of-memory killer) is
re-parented and would run its unit to the end, and on to the next, with nobody to read its
results. `exit_with_parent`, given to a pool as its ``initializer``, ends such a worker within
`PARENT_POLL` seconds (longer only while one call into Drake holds the interpreter). SIGTERM
ends Python without running ``finally`` blocks; `interrupt_on_sigterm` makes it raise
`Terminated`, a KeyboardInterrupt, so that a run stopped by ``kill`` cleans up as after Ctrl-C.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time

# how often a worker checks that its parent is alive, s; ours (an orphan's CPU for at most this)
PARENT_POLL = 0.5


def exit_with_parent() -> None:
    """A pool initializer: a daemon thread that ends this process at once (exit status 1, no
    clean-up) when its parent process is gone."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: raised in the main thread, handled like Ctrl-C (exit status 143)."""


def _raise_terminated(signum, frame) -> None:
    raise Terminated()


@contextlib.contextmanager
def interrupt_on_sigterm():
    """Within the block SIGTERM raises `Terminated` in the main thread; the handler before it
    is restored after. Outside the main thread (where Python takes no signal handler) it does
    nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def stop_workers(pool) -> None:
    """Ends a `concurrent.futures.ProcessPoolExecutor`'s workers now (SIGTERM), abandoning
    their tasks, and shuts the pool down without waiting for them."""
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14 and later
    if terminate is not None:
        terminate()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
