"""What was played: the emitted signals rangekit detects, with one interface.

Three kinds of emitted signal, each a frozen description with the same methods:

* :class:`Beep` (``kind == "beep"``): the tone-burst beep of Jiang et al. 2018 §4.3.1;
* :class:`CodedBurst` (``"coded"``): a Barker-coded (Kim & Kim 2013 §II-A) or SRF02 burst
  on a 40 kHz carrier;
* :class:`Probe` (``"probe"``): any waveform given as samples (a sweep, a lab's own file).

Every one has ``fs`` (the rate it is defined at), ``duration_s``, ``band()`` (its band
in Hz), ``check_fits(fs, what=...)`` (raises
:class:`~rangekit.errors.IncompatibleInputError` when a recording at ``fs`` cannot
carry it), ``samples_at(fs)`` (the signal as played at a recording's rate) and
``as_probe()`` (its samples as a :class:`Probe`, the matched-filter view of any of
them). Its structure stays on the class: a beep's bursts (``n_bursts``, ``spacing``), a
coded burst's ``code``. :func:`rangekit.detect.detect` takes any of them.

Examples
--------
>>> from rangekit.signals import Beep, CodedBurst, linear_sweep, signal_kind
>>> [signal_kind(s) for s in (Beep(), CodedBurst(), linear_sweep(500.0, 5000.0, 0.1))]
['beep', 'coded', 'probe']
>>> [round(f) for f in CodedBurst().band()]
[26667, 53333]
"""

from __future__ import annotations

from typing import Union

from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import CodedBurst
from rangekit.signals.beep import Beep, beep_waveform, burst_envelope, check_beep_fits
from rangekit.signals.probe import Probe, linear_sweep, read_probe

__all__ = [
    "SIGNAL_KINDS",
    "Beep",
    "CodedBurst",
    "Probe",
    "Signal",
    "beep_waveform",
    "burst_envelope",
    "check_beep_fits",
    "linear_sweep",
    "read_probe",
    "signal_kind",
]

#: Any emitted signal rangekit can detect.
Signal = Union[Beep, CodedBurst, Probe]  # noqa: UP007 (a runtime alias, also for 3.10 docs)

#: The kinds of emitted signal, as in each class's ``kind``.
SIGNAL_KINDS = ("beep", "coded", "probe")


def signal_kind(signal: object) -> str:
    """``signal.kind`` (one of :data:`SIGNAL_KINDS`) for an emitted signal.

    Raises
    ------
    InvalidParameterError
        ``signal`` is not a :class:`Beep`, :class:`CodedBurst` or :class:`Probe` (wrap bare
        samples as ``Probe(samples, fs)``).

    Examples
    --------
    >>> signal_kind([0.0, 1.0])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: signal=list must be a Beep, CodedBurst or Probe ...
    """
    if isinstance(signal, (Beep, CodedBurst, Probe)):
        return signal.kind
    raise InvalidParameterError(
        f"signal={type(signal).__name__} must be a Beep, CodedBurst or Probe "
        "(wrap samples as Probe(samples, fs))"
    )
