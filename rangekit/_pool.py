"""Stopping a worker pool at once and cleanly (``rangekit batch``, ``range --series``)."""

from __future__ import annotations

__all__ = ["stop_pool"]


def stop_pool(ex, *, timeout_s: float = 10.0) -> None:
    """Cancel the pending work of ``ex`` (a :class:`concurrent.futures.ProcessPoolExecutor`),
    terminate its workers and wait, at most ``timeout_s``, for its manager thread to end.

    Without the wait the manager thread closes its wake-up pipe while the interpreter's
    exit hook (``concurrent.futures.process._python_exit``, CPython 3.11) writes to it,
    unlocked: "OSError: [Errno 9] Bad file descriptor" and a traceback after a Ctrl-C of
    ``rangekit batch --jobs 2`` (seen once in three CI runs, 2026-12-04). The manager
    thread ends as soon as it sees the terminated workers; it joins them itself.
    """
    procs = list((getattr(ex, "_processes", None) or {}).values())
    thread = getattr(ex, "_executor_manager_thread", None)
    ex.shutdown(wait=False, cancel_futures=True)  # sets _processes to None: taken above
    for p in procs:
        p.terminate()
    if thread is not None:
        thread.join(timeout_s)
