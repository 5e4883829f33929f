"""Arrival detection: float sample indices with per-arrival quality and flags.

:func:`detect` is the one entry point for every emitted signal
(:mod:`rangekit.signals`: a :class:`~rangekit.signals.Beep`, a
:class:`~rangekit.signals.CodedBurst` or a :class:`~rangekit.signals.Probe`) and every
method (:data:`METHODS`). ``rangekit range``, ``detect``, ``batch``, ``calibrate``,
``--series`` and ``plot`` all detect through it, so they agree on the first path. The
methods stay importable on their own: :func:`detect_changepoint`, :func:`detect_xcorr`
and :func:`rangekit.detect.template.detect_template`.
"""

from __future__ import annotations

import numpy as np

from rangekit.detect.changepoint import detect_changepoint
from rangekit.detect.xcorr import detect_xcorr
from rangekit.errors import InvalidParameterError
from rangekit.signals import Signal, signal_kind
from rangekit.signals.beep import Beep
from rangekit.types import Arrivals

__all__ = [
    "DETECTORS",
    "METHODS",
    "detect",
    "detect_changepoint",
    "detect_xcorr",
    "method_for",
    "template_probe",
]

#: Methods per signal kind; the first is the default. ``changepoint``: STFT change points
#: refined by the bursts' edge fit (``docs/theory/beepbeep.md``); ``xcorr``: the whole
#: beep's matched-filter peak; ``template``: matched filtering with noise weighting and
#: first-path selection (``docs/theory/probes.md``), for coded bursts and probes;
#: ``fitted``: a coded burst's arrivals timed by the transducer fit of one-way ranging
#: (:func:`rangekit.detect.fitted.detect_coded`, the first paths ``range_oneway`` uses,
#: transducers of unknown Q; ``docs/theory/ultrasonic.md``). Not for
#: the beep: its 10 ms tone bursts give a matched-filter main lobe 20 ms wide, in which
#: the first path cannot be told from a reflection (measured: a reflection 117 samples
#: late taken in a 6 x 5 x 3 m room, confidence 1, no flag); its edges are what time it.
METHODS: dict[str, tuple[str, ...]] = {
    "beep": ("changepoint", "xcorr"),
    "coded": ("template", "fitted"),
    "probe": ("template",),
}

#: Method names for the built-in beep (``--detector``).
DETECTORS = METHODS["beep"]


def method_for(signal: Signal, method: str | None = None) -> str:
    """The method :func:`detect` uses for ``signal``: ``method`` checked, or the default.

    Examples
    --------
    >>> from rangekit.signals import Beep, linear_sweep
    >>> method_for(Beep()), method_for(linear_sweep(500.0, 5000.0, 0.1))
    ('changepoint', 'template')
    >>> method_for(linear_sweep(500.0, 5000.0, 0.1), "xcorr")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: method='xcorr' does not apply to a probe ...
    """
    kind = signal_kind(signal)
    allowed = METHODS[kind]
    if method is None:
        return allowed[0]
    if method not in allowed:
        known = sorted({m for ms in METHODS.values() for m in ms})
        if method not in known:
            raise InvalidParameterError(f"method={method!r} must be one of {', '.join(known)}")
        raise InvalidParameterError(
            f"method={method!r} does not apply to a {kind} signal; use {' or '.join(allowed)}"
        )
    return method


def detect(
    x: np.ndarray,
    *,
    fs: float,
    signal: Signal | None = None,
    method: str | None = None,
    expected: int | None = None,
    min_separation_s: float | None = None,
    what: str = "the recording",
    beep: Beep | None = None,
    detector: str | None = None,
    **kw,
) -> Arrivals:
    """Arrivals of ``signal`` in one channel, first path each, with quality and flags.

    Parameters
    ----------
    x : array_like, shape (n,)
        One channel of a recording.
    fs : float
        Its sample rate in Hz.
    signal : Beep, CodedBurst or Probe, optional
        What was played (default: the rangekit beep).
    method : str, optional
        One of ``METHODS[signal.kind]`` (default the first: ``changepoint`` for a beep,
        ``template`` otherwise).
    expected : int, optional
        Number of emissions in the channel (one per device of an exchange): at most this
        many arrivals, the best supported.
    min_separation_s : float, optional
        Shortest time between two emissions' starts (``template`` only; ``fitted``
        takes ``windows=``, one arrival per activation window, instead).
    what : str
        The recording, for messages.
    beep, detector
        The older spellings of ``signal`` (a beep) and ``method``.
    **kw
        Passed to the method: :func:`detect_changepoint`, :func:`detect_xcorr` or
        :func:`rangekit.detect.template.detect_template` (e.g. ``weighting``,
        ``spectra``). A coded burst's template is the drive through ``tx`` and ``rx``
        (transducers, default rangekit's 40 kHz resonator, Q 4, both ends).

    Returns
    -------
    Arrivals
        In time order; ``flags`` per arrival (:data:`rangekit.types.ARRIVAL_FLAGS`).

    Raises
    ------
    InvalidParameterError
        An unknown method, one that does not apply to the signal, or an option of another
        method.
    IncompatibleInputError
        ``fs`` cannot carry the signal.

    Examples
    --------
    >>> import numpy as np
    >>> len(detect(np.zeros(44100), fs=44100.0))
    0
    """
    if beep is not None:
        if signal is not None:
            raise InvalidParameterError("give signal or beep, not both")
        signal = beep
    if detector is not None:
        if method is not None:
            raise InvalidParameterError("give method or detector, not both")
        method = detector
    signal = Beep() if signal is None else signal
    method = method_for(signal, method)
    signal.check_fits(fs, what=what)
    if method == "fitted":  # one-way timing: the transducer fit (range_oneway's)
        from rangekit.detect.fitted import detect_coded

        if min_separation_s is not None or expected is not None:
            raise InvalidParameterError(
                "the fitted method takes windows=, not expected or min_separation_s"
            )
        return detect_coded(x, fs=fs, burst=signal, **kw)
    if method != "template":
        if min_separation_s is not None:
            raise InvalidParameterError(
                f"min_separation_s applies to the template method, not {method!r}"
            )
        if method == "changepoint":
            return detect_changepoint(x, fs=fs, beep=signal, expected=expected, **kw)
        return detect_xcorr(x, fs=fs, beep=signal, max_beeps=expected, **kw)
    from rangekit.detect.template import detect_template

    return detect_template(
        x,
        fs=fs,
        probe=template_probe(signal, fs=fs, tx=kw.pop("tx", None), rx=kw.pop("rx", None)),
        expected=expected,
        min_separation_s=min_separation_s,
        what=what,
        **kw,
    )


def template_probe(signal: Signal, *, fs: float, tx=None, rx=None):
    """The matched-filter template of ``signal`` as a Probe: the signal's samples, or for
    a coded burst the drive at ``fs`` through ``tx`` and ``rx`` (default rangekit's
    transducer, :class:`rangekit.signals.transducer.Transducer`, at both ends)."""
    if signal_kind(signal) != "coded":
        if tx is not None or rx is not None:
            raise InvalidParameterError("tx and rx apply to a coded burst only")
        return signal.as_probe()
    from rangekit.detect.matched import coded_template
    from rangekit.signals.probe import Probe
    from rangekit.signals.transducer import Transducer

    signal.check_fits(fs)
    tx = Transducer() if tx is None else tx
    rx = Transducer() if rx is None else rx
    h = coded_template(signal, fs=fs, tx=tx, rx=rx)
    return Probe(h, fs, name="coded burst")
