"""One session ranged into rows of the results file: two-way (BeepBeep) or ultrasonic, a
failure becoming one error row, never an exception (:func:`run_session`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rangekit.batch._options import BatchOptions
from rangekit.batch._results import BATCH_COLUMNS
from rangekit.batch._sessions import Session, _printable
from rangekit.errors import InputFileError, RangekitError


def _row(session: Session, scheme: str, **values: Any) -> dict[str, Any]:
    """One results row: every column of :data:`BATCH_COLUMNS`, None where missing;
    ``files`` the session's files as found (their folders kept), ``flags`` a list."""
    row: dict[str, Any] = dict.fromkeys(BATCH_COLUMNS)
    row.update(session=session.name, status="ok", scheme=scheme)
    row["files"] = [_printable(f) for f in session.files]
    row.update(values)
    return row


def _beepbeep_rows(session: Session, opts: BatchOptions) -> list[dict[str, Any]]:
    from rangekit.ranging import range_files
    from rangekit.signals import Beep

    kw = opts.beepbeep.kwargs()
    p = session.params
    if "beep" in p:
        keys = ("f_hz", "n_bursts", "spacing", "burst_len", "taper", "amplitude", "fs")
        kw["beep"] = Beep(**{k: p["beep"][k] for k in keys if k in p["beep"]})
    if "temp_c" in p and kw.get("speed_m_s") is None:
        kw["temp_c"] = p["temp_c"]
    if "self_distance_m" in p:
        kw["self_distance_m"] = p["self_distance_m"]
    result = range_files(list(session.files), scheme="beepbeep", **kw)
    truth = {(a, b): d for a, b, d in session.truth}
    truth.update({(b, a): d for a, b, d in session.truth})
    rows = []
    for r in result.ranges:
        rows.append(
            _row(
                session,
                "beepbeep",
                a=r.a,
                b=r.b,
                distance_m=r.distance_m,
                sigma_m=r.sigma_m,
                true_distance_m=truth.get((r.a, r.b)),
                flags=list(r.flags),
            )
        )
    return rows


def _ultrasonic_rows(session: Session, scheme: str, opts: BatchOptions) -> list[dict[str, Any]]:
    from rangekit.ranging.ultrasonic import range_ultrasonic_files

    kw = (opts.oneway if scheme == "oneway" else opts.echo).kwargs()
    p = session.params
    if "temp_c" in p and kw.get("speed_m_s") is None:
        kw["temp_c"] = p["temp_c"]
    if "period_s" in p:
        kw["period_s"] = p["period_s"]
    if "latency_s" in p and scheme == "oneway":
        kw["latency_s"] = p["latency_s"]
    if "tx_order" in p and scheme == "oneway" and kw.get("tx_ids") is None:
        kw["tx_ids"] = p["tx_order"]
    from rangekit.io.audio import check_period

    check_period(session.files, kw.get("period_s"))
    truth = {(w, c): d for w, c, d in session.truth}
    rows = []
    for r in range_ultrasonic_files(list(session.files), scheme=scheme, **kw):
        rows.append(
            _row(
                session,
                scheme,
                files=[_printable(str(r["file"]))],
                window=r["window"],
                tx=r.get("tx"),
                channel=r["channel"],
                distance_m=r["distance_m"],
                sigma_m=r["sigma_m"],
                true_distance_m=truth.get((r["window"], r["channel"])),
                snr_db=r["snr_db"],
                arrival_s=r["arrival_s"],
                flags=list(r.get("flags") or ()),
            )
        )
    return rows


def run_session(session: Session, options: BatchOptions) -> list[dict[str, Any]]:
    """Range one session; rows with the keys of :data:`BATCH_COLUMNS`.

    Never raises for a bad recording: a rangekit error (or any other exception) becomes
    one row with ``status="error"`` and the message in ``error``. Every row carries
    ``session_rows``, the number of rows of its session (the resume check).
    """
    scheme = session.scheme or options.scheme
    try:
        if session.problem is not None:
            raise InputFileError(session.problem)
        if scheme == "beepbeep":
            rows = _beepbeep_rows(session, options)
        else:
            rows = _ultrasonic_rows(session, scheme, options)
        if not rows:
            raise RangekitError("no range came out of this session")
    except RangekitError as e:
        rows = [_row(session, scheme, status="error", error=str(e))]
    except Exception as e:  # a bug must not stop the batch; it is reported in the row
        rows = [
            _row(session, scheme, status="error", error=f"internal error: {type(e).__name__}: {e}")
        ]
    for r in rows:
        r["session_rows"] = len(rows)
    return rows


def _run_chunk(sessions: Sequence[Session], options: BatchOptions) -> list[list[dict]]:
    return [run_session(s, options) for s in sessions]
