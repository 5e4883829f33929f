"""Probe signals to play, as ``rangekit design`` writes them: one call per design.

Each call returns a :class:`Design`: the signal designed (a :class:`~rangekit.signals.Beep`,
:class:`~rangekit.signals.barker.CodedBurst` or :class:`~rangekit.signals.probe.Probe`),
its samples at the file's rate and that rate; :meth:`Design.write` writes them as a 16-bit
PCM file (WAV, or FLAC, ... by the suffix). The checks are the signals' own
(:func:`~rangekit.signals.beep.check_beep_fits`, :class:`~rangekit.signals.barker.CodedBurst`,
:func:`~rangekit.signals.probe.check_sweep`); nothing is restated here.

Examples
--------
>>> d = design_sweep(17000.0, 20000.0, 0.1)
>>> d.fs, len(d.samples), d.signal.name
(44100.0, 4410, 'sweep 17000-20000 Hz, 0.1 s')
>>> d = design_beep(fs=48000.0)
>>> d.fs, len(d.samples)
(48000.0, 16807)
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Union

import numpy as np

from rangekit.signals.barker import CodedBurst, burst_waveform
from rangekit.signals.beep import Beep, beep_continuous, check_beep_fits
from rangekit.signals.probe import Probe, check_sweep, linear_sweep

__all__ = ["Design", "design_barker", "design_beep", "design_sweep"]


@dataclass(frozen=True, eq=False)
class Design:
    """A designed signal as it is written to a file.

    Attributes
    ----------
    signal : Beep, CodedBurst or Probe
        What was designed.
    samples : ndarray, shape (n,)
        The samples written, float64 within [-1, 1].
    fs : float
        The file's sample rate, Hz.
    """

    signal: Union[Beep, CodedBurst, Probe]  # noqa: UP007 (runtime annotation, 3.10 docs)
    samples: np.ndarray
    fs: float

    def write(self, path: str | os.PathLike) -> None:
        """Write the samples to ``path`` as 16-bit PCM at :attr:`fs` (the format by the
        suffix, :func:`rangekit.io.audio.write_audio`)."""
        from rangekit.io.audio import write_audio

        write_audio(path, self.samples, fs=self.fs, subtype="PCM_16")


def design_beep(beep: Beep | None = None, *, fs: float | None = None, what: str = "fs") -> Design:
    """The beep as ``rangekit design beep`` writes it: sampled at the file's rate ``fs``
    (None: the beep's own ``beep.fs``) from its continuous-time form
    (:func:`~rangekit.signals.beep.beep_continuous`), so it keeps its timing in seconds
    at any rate; ``ceil(duration_s * fs)`` samples.

    Raises
    ------
    IncompatibleInputError
        ``fs`` cannot carry the beep (:func:`~rangekit.signals.beep.check_beep_fits`; the
        message names the rate as ``what``).
    """
    beep = Beep() if beep is None else beep
    rate = beep.fs if fs is None else float(fs)
    check_beep_fits(beep, fs=rate, what=what)
    t = np.arange(int(math.ceil(beep.duration_s * rate))) / rate
    return Design(beep, beep_continuous(t, beep=beep), rate)


def design_barker(burst: CodedBurst | None = None) -> Design:
    """The coded burst as ``rangekit design barker`` writes it: its drive waveform
    (:func:`~rangekit.signals.barker.burst_waveform`) at its own rate ``burst.fs``."""
    burst = CodedBurst() if burst is None else burst
    return Design(burst, burst_waveform(burst), burst.fs)


def design_sweep(
    f0_hz: float,
    f1_hz: float,
    duration_s: float,
    *,
    fs: float = 44100.0,
    fade_s: float | None = None,
    amplitude: float = 0.5,
    names: dict[str, str] | None = None,
) -> Design:
    """The linear sweep as ``rangekit design sweep`` writes it
    (:func:`~rangekit.signals.probe.linear_sweep` of these arguments, at ``fs``).

    ``names`` (the caller's names of the arguments) are passed to
    :func:`~rangekit.signals.probe.check_sweep`: arguments that do not fit together then
    raise :class:`~rangekit.signals.probe.SweepError` naming them so.
    """
    if names is not None:
        check_sweep(f0_hz, f1_hz, duration_s, fs=fs, fade_s=fade_s, names=names)
    probe = linear_sweep(f0_hz, f1_hz, duration_s, fs=fs, fade_s=fade_s, amplitude=amplitude)
    return Design(probe, probe.samples, probe.fs)
