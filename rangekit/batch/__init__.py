"""Batch ranging of recording archives: sessions, parallel workers, a resumable results file.

A *session* is one ranging run: the recordings of one two-way exchange (one multichannel
file, or one mono file per device), or one ultrasonic log. :func:`find_sessions` groups
the inputs into sessions, :func:`run_session` ranges one (a failure becomes an error row,
never an exception), and :func:`run_batch` runs many in parallel -- in local processes or
on a Dask cluster -- appending each finished session to a :class:`ResultsFile` so that a
batch killed at any moment loses no finished result and can be resumed.

Grouping rules (``docs/batch.md``)
---------------------------------
1. **Sidecar.** A ``.json`` file with a ``"files"`` list (names relative to its folder;
   what ``rangekit synth`` writes) makes those files one session, named after the
   sidecar (its path without ``.json``). Sidecars are those in the folders searched and
   those next to an input file that is one of their ``files``. From the sidecar rangekit
   also takes ``scheme``, ``beep`` (the beep's parameters), ``temp_c``, the
   self-distances (a top-level ``self_distance_m``, number or list, or
   ``devices[i].self_distance_m``) and the true distances
   ``pairs[k] = {"a", "b", "distance_m"}`` (the ``true_distance_m`` column).
   For ``oneway`` and ``echo`` sidecars (``rangekit synth oneway|echo``): ``period_s``,
   ``latency_s`` (oneway) and the true distances of ``windows[k]`` (``distances_m`` per
   receiver, or the echo's ``distance_m``). Sidecar values override the command's
   options for that session.
2. **Naming rule.** Among the files no sidecar claims, ``NAME_dev0.wav``,
   ``NAME_dev1.wav``, ... in one folder (indices 0..N-1, no gap, N >= 2) are the mono
   recordings of devices 0..N-1 of session ``NAME``.
3. Every other audio file is a session of its own.
4. **Device folders paired by name** (:func:`pair_sessions_by_name`, ``rangekit batch
   --pair-by-name DIR0 DIR1 ...``; replaces rules 1-3). Folder i holds device i's mono
   recordings. Each recording (any of :data:`AUDIO_SUFFIXES`, searched recursively, names
   starting with ``.`` skipped) is keyed by its path relative to its folder without the
   suffix, case-sensitively (``dev1/day1/take_01.wav`` and ``dev2/day1/take_01.flac``:
   key ``day1/take_01``). Each key is one BeepBeep session named by the key, with the
   folders' files in device order; a key missing from some folder gives a session that
   fails naming those folders (nothing is dropped silently). Two files of one folder with
   the same key are an error. A sidecar ``KEY.json`` beside device 0's file gives the
   values of rule 1 (its ``files`` are ignored: the names decide).

Examples
--------
>>> rows = run_session(Session("missing", ("no_such.wav",)), BatchOptions())
>>> rows[0]["status"], rows[0]["error"].startswith("cannot open")
('error', True)
"""

# The package's modules, one concept each (docs/architecture.md):
#   _sessions  inputs expanded safely, grouped into sessions (rules 1-3)
#   _sidecars  the values a sidecar gives, type- and range-checked
#   _pairing   device folders paired by name (rule 4)
#   _options   BatchOptions (its two-way part TwoWayOptions), option values as JSON
#   _ranging   one session -> rows (run_session)
#   _results   the results file, its metadata file, resume, iter_rows
#   _run       run_batch: local worker processes
#   _dask      the Dask cluster: address, connection, watchdog
# Two private names stay importable from the package (the tests of the sidecar checks
# and of the Dask watchdog import them from here): the `X as X` re-exports below.

from __future__ import annotations

from rangekit.batch._dask import (
    DASK_CONNECT_TIMEOUT_S,
    DASK_WATCHDOG_S,
    check_scheduler_address,
)
from rangekit.batch._dask import _dask_watch as _dask_watch
from rangekit.batch._options import (
    SCHEMES,
    BatchOptions,
    TwoWayOptions,
    UltrasonicOptions,
    json_value,
)
from rangekit.batch._pairing import pair_sessions_by_name
from rangekit.batch._ranging import run_session
from rangekit.batch._results import (
    BATCH_COLUMNS,
    COLUMN_TYPES,
    LIST_SEPARATOR,
    ResultsFile,
    iter_rows,
    meta_path,
)
from rangekit.batch._run import BatchSummary, run_batch
from rangekit.batch._sessions import AUDIO_SUFFIXES, Session, find_sessions
from rangekit.batch._sidecars import MAX_SIDECAR_FILES
from rangekit.batch._sidecars import _sidecar_values as _sidecar_values

__all__ = [
    "AUDIO_SUFFIXES",
    "BATCH_COLUMNS",
    "COLUMN_TYPES",
    "DASK_CONNECT_TIMEOUT_S",
    "DASK_WATCHDOG_S",
    "LIST_SEPARATOR",
    "MAX_SIDECAR_FILES",
    "SCHEMES",
    "BatchOptions",
    "BatchSummary",
    "ResultsFile",
    "Session",
    "TwoWayOptions",
    "UltrasonicOptions",
    "check_scheduler_address",
    "find_sessions",
    "iter_rows",
    "json_value",
    "meta_path",
    "pair_sessions_by_name",
    "run_batch",
    "run_session",
]
