"""``rangekit._pool.stop_pool``: a worker pool stopped at once leaves nothing running.

After a Ctrl-C of ``rangekit batch --jobs 2`` the pool was shut down without waiting and
its workers terminated; its manager thread then closed its wake-up pipe while the
interpreter's exit hook wrote to it, and a traceback ("OSError: [Errno 9] Bad file
descriptor") reached the user (``tests/test_hostile_hangs.py``, once in three CI runs).
``stop_pool`` waits for the manager thread, so the pipe is closed before the exit hook.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import sys
import time

import pytest

from rangekit._pool import stop_pool


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_stop_pool_ends_the_workers_and_the_manager_thread():
    ex = cf.ProcessPoolExecutor(max_workers=2, mp_context=mp.get_context("fork"))
    futs = [ex.submit(time.sleep, 30) for _ in range(4)]
    deadline = time.monotonic() + 10
    while not any(f.running() for f in futs) and time.monotonic() < deadline:
        time.sleep(0.01)
    procs = list(ex._processes.values())
    thread, wakeup = ex._executor_manager_thread, ex._executor_manager_thread_wakeup
    stop_pool(ex)  # the 30 s sleeps are terminated, not waited for
    assert not thread.is_alive()
    assert wakeup._closed  # what the interpreter's exit hook checks before writing
    assert all(not p.is_alive() for p in procs)
    assert all(f.cancelled() or f.done() for f in futs)
