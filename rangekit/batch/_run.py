"""Running a batch: sessions sent in chunks to local worker processes or a Dask cluster,
each finished session appended to the results file (:func:`run_batch`)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rangekit.batch._dask import _run_dask, check_scheduler_address
from rangekit.batch._options import BatchOptions
from rangekit.batch._ranging import _run_chunk, run_session
from rangekit.batch._results import ResultsFile
from rangekit.batch._sessions import Session
from rangekit.errors import InvalidParameterError


@dataclass(frozen=True)
class BatchSummary:
    """Counts of a finished batch over its sessions: ``total``; ``skipped`` (found done
    in a resumed file); ``ok`` and ``failed`` (status of every session in the file, the
    skipped ones included); the output ``path``; and ``first_error``, the first failed
    session in session order with its message (``"NAME: MESSAGE"``, None if none failed)."""

    total: int
    skipped: int
    ok: int
    failed: int
    path: str
    first_error: str | None = None


#: Tasks per worker the default chunk aims at: the last task decides how long the other
#: workers wait idle, so it must be short (a task costs ~1 ms to send and return, a
#: session 0.05-0.5 s). With 4 tasks per worker, 60 sessions went in chunks of 7: a
#: worker could finish up to 7 sessions after the other; now at most one.
TASKS_PER_WORKER = 16


def default_chunk(n_sessions: int, workers: int) -> int:
    """Sessions per task: ``n_sessions / (16 workers)``, between 1 and 16.

    Examples
    --------
    >>> default_chunk(60, 2), default_chunk(1000, 2), default_chunk(10_000, 4)
    (1, 16, 16)
    """
    return max(1, min(16, n_sessions // (TASKS_PER_WORKER * max(1, workers))))


def _chunks(items: Sequence[Session], size: int) -> list[list[Session]]:
    return [list(items[i : i + size]) for i in range(0, len(items), size)]


def _pool_initializer() -> None:
    """Workers leave Ctrl-C to the parent (which stops them and keeps what is written),
    and on Linux die with it (a parent killed by SIGKILL leaves no orphan working on)."""
    import signal
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


def run_batch(
    sessions: Sequence[Session],
    output: str | os.PathLike,
    options: BatchOptions | None = None,
    *,
    jobs: int = 1,
    resume: bool = False,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    chunk: int | None = None,
) -> BatchSummary:
    """Range ``sessions`` and write every result row to ``output``.

    Parameters
    ----------
    sessions : sequence of Session
        From :func:`find_sessions`.
    output : str or os.PathLike
        The results file, ``.csv`` or ``.jsonl`` (:class:`ResultsFile`).
    options : BatchOptions, optional
        Defaults for sessions without a sidecar value.
    jobs : int
        Worker processes (1: in this process). Ignored with ``scheduler``.
    resume : bool
        Continue ``output``: sessions already in it are skipped.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://HOST:PORT``); needs the optional
        ``dask[distributed]`` (``pip install rangekit[dask]``).
    progress : callable, optional
        Called as ``progress(done, total)`` after each session (``done`` counts skipped
        sessions too).
    chunk : int, optional
        Sessions per task sent to a worker; default :func:`default_chunk` (about 16
        tasks per worker, at most 16 sessions a task).

    Returns
    -------
    BatchSummary

    Notes
    -----
    On an interrupt (Ctrl-C) the workers are stopped, every session finished so far is in
    the file, and ``KeyboardInterrupt`` propagates; rerun with ``resume=True``.
    """
    options = BatchOptions() if options is None else options
    jobs = int(jobs)
    if jobs < 1:
        raise InvalidParameterError(f"jobs={jobs} must be >= 1")
    if scheduler is not None:
        check_scheduler_address(scheduler)
    results = ResultsFile(output, options, resume=resume)
    order = [s.name for s in sessions]
    todo = [s for s in sessions if s.name not in results.done]
    total = len(sessions)
    skipped = total - len(todo)
    done = skipped
    if progress is not None:
        progress(done, total)

    def record(rows: list[dict]) -> None:
        nonlocal done
        results.append(rows)
        done += 1
        if progress is not None:
            progress(done, total)

    workers = jobs if scheduler is None else 4
    size = chunk or default_chunk(len(todo), workers)
    try:
        if scheduler is not None:
            _run_dask(scheduler, _chunks(todo, size), options, record)
        elif jobs == 1 or len(todo) <= 1:
            for s in todo:
                record(run_session(s, options))
        else:
            _run_pool(jobs, _chunks(todo, size), options, record)
    finally:
        results.close()
    ok = sum(results.status.get(n) == "ok" for n in order)
    failed = sum(results.status.get(n) == "error" for n in order)
    first = next((f"{n}: {results.errors[n]}" for n in order if n in results.errors), None)
    summary = BatchSummary(total, skipped, ok, failed, str(results.path), first)
    results.finish(order)
    return summary


def _import_ranging() -> None:
    """Import what a session's ranging imports on first use (~0.2 s CPU), so that forked
    workers share it instead of each importing it again."""
    import rangekit.detect.changepoint
    import rangekit.ranging.pipeline
    import rangekit.ranging.ultrasonic  # noqa: F401


def _run_pool(jobs: int, chunks: list[list[Session]], options, record) -> None:
    import concurrent.futures as cf
    import multiprocessing as mp

    # fork starts workers in milliseconds with rangekit (and numba's compiled kernels)
    # already loaded; elsewhere spawn.
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    if ctx.get_start_method() == "fork":
        _import_ranging()  # once here, not once per worker
    ex = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_pool_initializer)
    try:
        futs = [ex.submit(_run_chunk, c, options) for c in chunks]
        for f in cf.as_completed(futs):
            for rows in f.result():
                record(rows)
    except BaseException:
        from rangekit._pool import stop_pool

        stop_pool(ex)
        raise
    ex.shutdown(wait=True)
