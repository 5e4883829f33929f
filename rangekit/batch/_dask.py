"""A batch on a Dask distributed cluster: the scheduler's address checked, a connection
that cannot hang, and a watchdog that stops the batch when the cluster loses its
workers.

The timeouts are read from the package (``rangekit.batch.DASK_CONNECT_TIMEOUT_S``,
``rangekit.batch.DASK_WATCHDOG_S``) when they are used, so that setting them there takes
effect."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from rangekit.batch._ranging import _run_chunk
from rangekit.errors import InputFileError, InvalidParameterError

if TYPE_CHECKING:
    from rangekit.batch._sessions import Session

#: Seconds to wait for a Dask scheduler to answer before giving up.
DASK_CONNECT_TIMEOUT_S = 10.0
#: Seconds without a finished Dask task after which the batch checks that the cluster
#: still has workers (none: the batch stops with exit 3 instead of waiting forever).
DASK_WATCHDOG_S = 30.0


def _setting(name: str) -> float:
    """The package's value of the setting ``name`` (``rangekit.batch.NAME``), read when it
    is used: where a user or a test sets it."""
    import rangekit.batch

    return float(getattr(rangekit.batch, name))


_ADDRESS_RE = re.compile(
    r"^(?:(?P<proto>tcp|tls)://)?(?P<host>\[[0-9a-fA-F:]+\]|[^\s:/\[\]]+):(?P<port>\d{1,5})$"
)


def check_scheduler_address(address: str) -> re.Match:
    """The parts of a ``[tcp://|tls://]HOST:PORT`` address, else InvalidParameterError."""
    m = _ADDRESS_RE.match(str(address).strip())
    if m is None or not 0 < int(m["port"]) < 65536:
        raise InvalidParameterError(
            f"--scheduler {address!r} is not an address of the form tcp://HOST:PORT"
        )
    return m


def _dask_client(Client, address: str):
    """A connected Dask client, or an error within about DASK_CONNECT_TIMEOUT_S.

    The address must be ``[tcp://|tls://]HOST:PORT`` (else InvalidParameterError). The
    TCP connection and then the Dask handshake each get the timeout: a server that
    accepts and never answers, or is not a Dask scheduler, is an InputFileError naming
    the address, not a hang."""
    import socket
    import threading

    m = check_scheduler_address(address)
    t = _setting("DASK_CONNECT_TIMEOUT_S")
    where = f"the Dask scheduler at {address}"
    try:
        socket.create_connection((m["host"].strip("[]"), int(m["port"])), timeout=t).close()
    except OSError as e:
        raise InputFileError(f"cannot connect to {where}: {e.strerror or e}") from None
    box: dict[str, Any] = {}

    def connect() -> None:
        try:
            box["client"] = Client(address.strip(), timeout=f"{t}s")
        except BaseException as e:  # reported in the caller's thread
            box["error"] = e

    th = threading.Thread(target=connect, daemon=True, name="rangekit-dask-connect")
    th.start()
    th.join(t + 5.0)
    if th.is_alive():
        raise InputFileError(
            f"cannot connect to {where}: no Dask handshake within {t:g} s (is it a Dask scheduler?)"
        )
    if "error" in box:
        e = box["error"]
        raise InputFileError(f"cannot connect to {where}: {type(e).__name__}: {e}") from None
    return box["client"]


def _run_dask(address: str, chunks: list[list[Session]], options, record) -> None:
    try:
        from distributed import Client
    except ImportError:
        raise InvalidParameterError(
            "--scheduler needs Dask: pip install 'rangekit[dask]' (dask[distributed])"
        ) from None
    from distributed import wait

    client = _dask_client(Client, address)
    try:
        futs = [client.submit(_run_chunk, c, options, pure=False) for c in chunks]
        _dask_watch(client, futs, record, address=address, wait=wait)
    finally:
        client.close()


def _dask_watch(client, futs, record, *, address: str, wait) -> None:
    """Record the chunks' rows as their tasks finish, watching the cluster.

    Every :data:`DASK_WATCHDOG_S` without a finished task the scheduler is asked for its
    workers: none left (they died), or no answer, stops the batch with an InputFileError
    (exit 3) instead of waiting forever; so does a task that failed on the cluster (a
    worker killed while running it, ``KilledWorker``). Every session finished before is
    in the results file (rerun with ``--resume``)."""
    pending = set(futs)
    where = f"the Dask cluster at {address}"
    again = "every finished session is in the results file; rerun with --resume"
    while pending:
        try:
            done, pending = wait(
                pending, timeout=_setting("DASK_WATCHDOG_S"), return_when="FIRST_COMPLETED"
            )
        except TimeoutError:
            try:
                workers = client.scheduler_info().get("workers", {})
            except Exception as e:
                raise InputFileError(f"lost {where} ({type(e).__name__}: {e}); {again}") from None
            if not workers:
                raise InputFileError(
                    f"{where} has no worker left: {len(pending)} task(s) cannot run; {again}"
                ) from None
            continue
        for f in done:
            try:
                chunk = f.result()
            except Exception as e:  # KilledWorker, a worker's own failure
                raise InputFileError(
                    f"a task failed on {where} ({type(e).__name__}: {e}); {again}"
                ) from None
            for rows in chunk:
                record(rows)
