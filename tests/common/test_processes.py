"""Pool workers end with their parent; SIGTERM reads as an interrupt and the handler before it
comes back."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drake_clutter.common.processes import Terminated, interrupt_on_sigterm
from drake_clutter.testing.processes import alive

REPO = Path(__file__).resolve().parents[2]

# A parent that starts one pool worker (with or without the initializer), prints the worker's
# pid, hands it a minute's sleep and waits.
PARENT = """
import os, sys, time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from drake_clutter.common.processes import exit_with_parent
init = exit_with_parent if sys.argv[1] == "watched" else None
pool = ProcessPoolExecutor(1, mp_context=get_context("spawn"), initializer=init)
print(pool.submit(os.getpid).result(), flush=True)
pool.submit(time.sleep, 60)
time.sleep(60)
"""


def _orphan(kind: str) -> int:
    """The pid of a pool worker whose parent was just killed with SIGKILL."""
    parent = subprocess.Popen([sys.executable, "-c", PARENT, kind], cwd=REPO,
                              stdout=subprocess.PIPE, text=True)
    worker = int(parent.stdout.readline())
    assert alive(worker)
    parent.kill()
    parent.wait()
    return worker


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_pool_worker_ends_when_its_parent_is_killed():
    worker = _orphan("watched")
    deadline = time.monotonic() + 10.0
    while alive(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(worker)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_without_the_watch_the_orphan_runs_on():
    """What the initializer is for: the same worker without it outlives its parent."""
    worker = _orphan("unwatched")
    try:
        time.sleep(2.0)
        assert alive(worker)
    finally:
        os.kill(worker, signal.SIGKILL)


def test_sigterm_raises_terminated_inside_and_the_old_handler_returns_after():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated), interrupt_on_sigterm():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5.0)  # the handler runs between bytecodes, long before this ends
    assert signal.getsignal(signal.SIGTERM) is before
    assert issubclass(Terminated, KeyboardInterrupt)
