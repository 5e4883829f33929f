"""Matched filtering of coded ultrasonic bursts, block by block, with first-path selection.

The pipeline for one channel:

1. **Template** (:func:`coded_template`): the emitted drive (a
   :class:`~rangekit.signals.barker.CodedBurst`) sampled at the recording's rate, optionally
   passed through the transmitter and receiver transducer models; sample 0 of the template
   is the drive's first sample, so a correlation peak at lag ``tau`` means "the drive that
   started at ``t = 0`` arrived ``tau`` samples later" and every transducer delay is
   removed when the responses are folded in.
2. **Analytic correlation** (:class:`MatchedFilter`): the recording is correlated with the
   analytic template ``h + j H{h}`` (``H`` = Hilbert transform), which gives the analytic
   signal of the matched-filter output; its magnitude is the envelope, free of the carrier
   ripple. The analytic template is an FIR filter (truncated where less than 1e-9 of its
   energy is left), so overlap-save on blocks gives exactly the whole-signal result; memory
   is bounded by the block size (:meth:`MatchedFilter.stream`).
3. **First path** (:func:`first_path`): the earliest local maximum of the envelope above
   ``max(k_noise * noise, rel_threshold * strongest)``, so that a reflection stronger than the
   direct path does not win (Kim & Kim 2013 use the peak of the matched filter; the
   first-path rule is rangekit's, see ``docs/theory/ultrasonic.md``).
4. **Sub-sample peak** (:func:`interp_peak`): a parabola through the logarithm of the
   three envelope samples around the maximum (exact for a Gaussian-shaped peak).

The 1-sigma of each arrival is the Cramér–Rao bound for a delay with unknown amplitude and
carrier phase, ``1 / (2 pi beta snr)``, with ``beta`` the RMS bandwidth of the template's
complex envelope about its centre frequency
(:func:`rangekit.signals.spectrum.rms_bandwidth_hz`) and ``snr`` the
measured peak-to-noise ratio of the matched-filter output (``snr^2 = 2 E / N0``).

Examples
--------
>>> from rangekit.signals.barker import CodedBurst, burst_waveform
>>> fs = 192000.0
>>> h = coded_template(CodedBurst(), fs=fs, tx=None, rx=None)
>>> x = np.zeros(4000)
>>> x[1000 : 1000 + len(h)] = h
>>> env = np.abs(MatchedFilter(h).correlate(x))
>>> i = int(np.argmax(env)); i
1000
>>> round(i + interp_peak(env, i)[0], 6)
1000.0
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect._fft import pocketfft
from rangekit.detect._kernel_choice import kernel_by_length
from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import CodedBurst, burst_waveform, check_burst_fits
from rangekit.signals.spectrum import rms_bandwidth_hz
from rangekit.signals.transducer import Transducer, apply_chain
from rangekit.types import Arrivals, flag_bit

__all__ = [
    "DEFAULT_BLOCK",
    "WEIGHTINGS",
    "MatchedFilter",
    "PathPeak",
    "Spectra",
    "coded_template",
    "common_spectra",
    "crb_delay_s",
    "detect_matched",
    "first_path",
    "interp_peak",
    "matched_filter",
    "noise_level",
    "weighting_response",
    "welch_spectra",
    "zero_phase_taps",
]

#: Default FFT size of the overlap-save blocks (samples).
DEFAULT_BLOCK = 1 << 15
#: Fraction of the template's energy the truncated analytic FIR may leave out.
_ANALYTIC_TAIL = 1e-9
#: Default noise multiple an earlier path must clear to win over the strongest peak: a
#: Rayleigh envelope exceeds 6 sigma with probability exp(-6^2 / 2) = 1.5e-8 per sample.
DEFAULT_K_NOISE = 6.0
#: Default noise multiple the strongest peak must clear for any detection (4.5 sigma:
#: probability exp(-4.5^2 / 2) = 4e-5 per sample of a false detection on noise alone).
DEFAULT_K_DETECT = 4.5
#: Default threshold relative to the strongest peak (-12 dB): a reflection up to 12 dB
#: stronger than the direct path still leaves the direct path above it; Barker-7's
#: autocorrelation side lobes sit at 1/7 (-17 dB).
DEFAULT_REL_THRESHOLD = 0.25
#: Smallest noise level, relative to the window's strongest envelope value (-120 dB): a
#: noiseless synthetic signal's rounding noise must not count as a noise floor.
NOISE_FLOOR_REL = 1e-6
#: sqrt(2 ln 2): the median of a Rayleigh variable in units of its scale.
_RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))


def coded_template(
    burst: CodedBurst | None = None,
    *,
    fs: float,
    tx: Transducer | None = None,
    rx: Transducer | None = None,
    tail_db: float = 60.0,
) -> np.ndarray:
    """The matched-filter template: the drive at ``fs``, through ``tx`` then ``rx``.

    Parameters
    ----------
    burst : CodedBurst, optional
        The emitted drive (default Barker-7, 40 kHz, 3 cycles per bit). Its ``fs`` is
        replaced by ``fs``.
    fs : float
        Sample rate of the recording in Hz; must carry the burst's band.
    tx, rx : Transducer or None
        Transducer responses to fold in (None = leave out). Folding the responses the
        recording went through removes their delay from the arrival times.
    tail_db : float
        The transducers' ringing tail is cut where the remaining energy is ``tail_db`` below
        the total (default 60 dB).

    Returns
    -------
    numpy.ndarray
        Template samples; index 0 is the drive's first sample.
    """
    burst = CodedBurst() if burst is None else burst
    fs = V.sample_rate(fs)
    check_burst_fits(burst, fs=fs, what="template")
    V.positive("tail_db", tail_db)
    drive = burst_waveform(burst.with_fs(fs))
    if tx is None and rx is None:
        return drive
    q = max(t.q for t in (tx, rx) if t is not None)
    f0 = min(t.f0_hz for t in (tx, rx) if t is not None)
    # A resonator's envelope decays as exp(-pi f0 t / Q): 60 dB takes ~2.2 Q / f0 each.
    # Rendered for 8x that: higher-order elements (a 6th-order Butterworth) ring longer,
    # and the cut below is relative to the rendered energy (4x left out up to 1.6x the
    # tail's share).
    n_tail = int(math.ceil(8.0 * (tail_db / 20.0) * math.log(10.0) * q / (math.pi * f0) * fs))
    y = _through((tx, rx), np.concatenate([drive, np.zeros(n_tail)]), fs)
    e = np.cumsum(y[::-1] ** 2)[::-1]
    keep = int(np.searchsorted(-e, -e[0] * 10.0 ** (-tail_db / 10.0)))
    return np.ascontiguousarray(y[: max(keep, len(drive))])


def _through(transducers, x: np.ndarray, fs: float) -> np.ndarray:
    """``apply_chain(x, transducers, fs=fs)``, rangekit's resonators without scipy.signal.

    A :class:`Transducer` (exactly that class) is its biquad run here by
    :func:`_biquad`, the same numbers as its ``apply`` (``scipy.signal.lfilter``; tested):
    the one-way command builds its template before anything else would import
    ``scipy.signal``, whose import alone cost 0.4-1.3 s (with ``scipy.stats``). Any other
    transducer class filters by its own ``apply``.
    """
    y = np.asarray(x, dtype=np.float64)
    for t in transducers:
        if t is None:
            continue
        if type(t) is Transducer:
            y = _biquad(*t.coefficients(fs=fs), y)
        else:
            y = apply_chain(y, (t,), fs=fs)
    return y


def _biquad(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter(b, a, x)`` of a biquad (3 taps each, zero initial state),
    bit for bit: the coefficients divided by ``a[0]``, then per sample the transposed
    direct form II in lfilter's order of operations (``y = z0 + b0 x``, ``z0 = z1 + x b1
    - y a1``, ``z1 = x b2 - y a2``; scipy's ``_lfilter`` C loop). A Python loop: for the
    templates' few hundred samples (0.2 ms), not for recordings."""
    a0 = float(a[0])
    b0, b1, b2 = (float(v) / a0 for v in b)
    _, a1, a2 = (float(v) / a0 for v in a)
    z0 = z1 = 0.0
    out = []
    for xn in x.tolist():
        yn = z0 + b0 * xn
        z0 = z1 + xn * b1 - yn * a1
        z1 = xn * b2 - yn * a2
        out.append(yn)
    return np.array(out, dtype=np.float64)


def _analytic_fir(h: np.ndarray, tail: float = _ANALYTIC_TAIL) -> tuple[np.ndarray, int]:
    """The analytic version of real FIR ``h`` as a finite complex FIR.

    Returns ``(g, pre)`` with ``g[k + pre] = h_a[k]`` for ``k`` in ``[-pre, len(g) - pre)``;
    the Hilbert transform's tails are cut where less than ``tail`` of the energy is left.
    """
    n_h = len(h)
    n = 1 << int(math.ceil(math.log2(16 * n_h + 64)))
    spec = np.fft.fft(h, n)
    spec[n // 2 + 1 :] = 0.0
    spec[1 : n // 2] *= 2.0
    ha = np.fft.ifft(spec)  # circular: negative times wrap to the end
    ha = np.roll(ha, n // 2)  # now index n // 2 is time 0
    e = np.abs(ha) ** 2
    total = e.sum()
    c = np.cumsum(e)
    lo = int(np.searchsorted(c, 0.5 * tail * total))
    hi = int(np.searchsorted(c, (1.0 - 0.5 * tail) * total)) + 1
    lo = min(lo, n // 2)
    hi = max(hi, n // 2 + n_h)
    return np.ascontiguousarray(ha[lo:hi]), n // 2 - lo


#: Fewest overlap-save blocks :meth:`MatchedFilter.stream` transforms per FFT call: scipy's
#: pocketfft runs several rows of one call in SIMD lanes (8 float32 / 4 float64 with
#: AVX2), so 2-block calls (a 2^16-sample chunk, 2^15-point blocks) cost ~1.7x per
#: block what 8-block calls cost (measured 190 vs 111 us per float32 row). The
#: output is the same bit for bit (each row's transform does not depend on the batch).
STREAM_MIN_BLOCKS = 8
#: FFT precisions of :class:`MatchedFilter` (input float, spectrum complex).
DTYPES = {"float64": (np.float64, np.complex128), "float32": (np.float32, np.complex64)}
#: Fraction of the analytic FIR's energy a decimated envelope's band may leave out
#: (:meth:`MatchedFilter.envelope`): an RMS error of ``sqrt(1e-5)`` = 0.3 % of the
#: output's RMS at most (the largest single error measured 0.55-0.63 %; tested <= 1.1 %).
DECIMATE_TAIL = 1e-5
#: Decimations the envelope may use (the largest whose band holds the FIR is taken).
DECIMATIONS = (8, 4, 2)
#: Largest relative difference of a float32 :meth:`MatchedFilter.correlate` from the
#: float64 one, in units of the output's largest magnitude (measured 1.5e-7 to 2.0e-7 on
#: 0.5-60 s of 192 kHz noise and bursts; tested).
FLOAT32_RTOL = 2e-6


def _check_x(name: str, x) -> np.ndarray:
    """``x`` as a 1-D contiguous float32 or float64 array of finite samples.

    float32 and float64 arrays are kept as they are (no float64 copy of a float32
    recording); anything else goes through :func:`rangekit._validate.signal_1d`.
    One pass each for the largest and smallest value (NaN propagates through both).
    """
    a = np.asarray(x)
    if a.dtype not in (np.float32, np.float64):
        return V.signal_1d(name, x, max_abs=V.MAX_SAMPLE_ABS)
    if a.ndim != 1:
        raise InvalidParameterError(f"{name} must be 1-D, got shape {a.shape}")
    a = np.ascontiguousarray(a)
    if a.size:
        hi, lo = float(np.max(a)), float(np.min(a))
        if not (math.isfinite(hi) and math.isfinite(lo)):
            raise InvalidParameterError(f"{name} contains NaN or infinite values")
        if max(hi, -lo) > V.MAX_SAMPLE_ABS:
            raise InvalidParameterError(
                f"{name} holds values beyond +-{V.MAX_SAMPLE_ABS:g} (their energy overflows)"
            )
    return a


def _ws_array(ws: dict, name: str, shape: tuple, dtype) -> np.ndarray:
    """An array of ``shape`` from the workspace ``ws`` (a view of its buffer ``name``,
    grown when too small; contents undefined)."""
    size = math.prod(shape)
    buf = ws.get(name)
    if buf is None or buf.dtype != dtype or len(buf) < size:
        buf = ws[name] = np.empty(size, dtype=dtype)
    return buf[:size].reshape(shape)


def _block_batches(x: np.ndarray, lead: int, step: int, n: int, n_blocks: int, per: int):
    """Overlap-save blocks ``v[b step : b step + n]`` of ``v = [0] * lead + x + [0] * ...``.

    Yields ``(b0, blocks)`` with ``blocks`` of shape ``(<= per, n)``: the blocks that lie
    inside ``x`` are strided views of it (no copy); only the first and last few, which
    reach into the zero padding, are copied into padded arrays.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    nx = len(x)
    b_lo = min(n_blocks, -(-lead // step))  # first block starting inside x
    b_hi = max(b_lo, min(n_blocks, (nx + lead - n) // step + 1)) if nx + lead >= n else b_lo

    def padded(b0: int, b1: int) -> np.ndarray:
        s0 = b0 * step - lead
        m = (b1 - b0 - 1) * step + n
        buf = np.zeros(m, dtype=x.dtype)
        lo, hi = max(s0, 0), min(s0 + m, nx)
        if hi > lo:
            buf[lo - s0 : hi - s0] = x[lo:hi]
        return sliding_window_view(buf, n)[::step]

    pieces = []
    if b_lo > 0:
        pieces.append((0, padded(0, b_lo)))
    if b_hi > b_lo:
        s0 = b_lo * step - lead
        pieces.append((b_lo, sliding_window_view(x[s0:], n)[::step][: b_hi - b_lo]))
    if n_blocks > b_hi:
        pieces.append((b_hi, padded(b_hi, n_blocks)))
    for b_start, win in pieces:
        for i in range(0, len(win), per):
            yield b_start + i, win[i : i + per]


class MatchedFilter:
    """Analytic matched filter (complex correlation) by overlap-save FFT blocks.

    ``correlate(x)[tau] = sum_k x[tau + k] * conj(h_a[k])`` for every lag ``tau`` in
    ``[0, len(x))``, where ``h_a`` is the analytic template; samples of ``x`` outside the
    array count as zero. ``abs()`` of it is the matched-filter envelope.

    Parameters
    ----------
    template : array_like
        Real template; index 0 is the time origin of a match.
    block : int
        FFT size of the overlap-save blocks (default 2^15); raised to fit the template.
    tail : float
        Fraction of the analytic template's energy its truncated FIR may leave out
        (default 1e-9). The Hilbert transform of a probe reaching down to tens of hertz
        decays slowly: a 1 s 20 Hz-20 kHz sweep needs 810k taps at 1e-9, 227k at 1e-7.
    dtype : {"float64", "float32"}
        Precision of the FFTs (default float64). float32 is 1.5-1.8x faster (measured) and
        differs from float64 by less than ``FLOAT32_RTOL`` of the output's largest
        magnitude (tested), far below the quantisation of a 16-bit recording.

    Notes
    -----
    The analytic correlation's spectrum ``X(f) conj(H_a(f))`` is one-sided and as
    band-limited as the template, so its samples at every ``D``-th lag are the inverse
    FFT of ``n / D`` bins around the template's band: :meth:`envelope` computes the
    envelope at ``D`` times fewer lags for one forward FFT and a ``D`` times shorter
    inverse FFT per block (complex baseband, Lyons, *Understanding Digital Signal
    Processing*, 3rd ed., §13.1; ``D`` the largest of ``DECIMATIONS`` whose band holds
    all but ``DECIMATE_TAIL`` of the FIR's energy: 4 for the Barker-7 template through
    two Q 4 transducers at 192 kHz, band 16.4-64.4 kHz).
    """

    def __init__(
        self,
        template: np.ndarray,
        *,
        block: int = DEFAULT_BLOCK,
        tail: float = _ANALYTIC_TAIL,
        dtype: str = "float64",
    ) -> None:
        h = V.signal_1d("template", template)
        if len(h) < 2 or not np.any(h):
            raise InvalidParameterError("template must have at least 2 samples, not all zero")
        if dtype not in DTYPES:
            raise InvalidParameterError(f"dtype={dtype!r} must be one of {', '.join(DTYPES)}")
        self.template = h
        self.energy = float(h @ h)
        self.dtype = dtype
        g, pre = _analytic_fir(h, V.in_range("tail", tail, 0.0, 0.1))
        self._set_fir(g, pre, V.positive_int("block", block, minimum=16))

    def _set_fir(self, g: np.ndarray, pre: int, block: int) -> None:
        """Use the complex FIR ``g`` (``g[k + pre]`` = analytic template at lag ``k``)."""
        self.pre = pre
        self.n_taps = len(g)
        self.block = block
        n = block
        while n < 4 * self.n_taps:
            n *= 2
        self.n_fft = n
        self.step = n - self.n_taps + 1
        from scipy import fft as sfft

        self._fft = sfft
        cdt = DTYPES[self.dtype][1]
        # Correlation with g = convolution with conj(g) reversed; the FFT of the taps
        # placed at [0, n_taps) correlates x_seg[j + k] with g[k].
        self._gr = np.conj(sfft.rfft(g.real, n)).astype(cdt)
        self._gi = (-np.conj(sfft.rfft(g.imag, n))).astype(cdt)
        # The decimated envelope's band: n / D bins [k0, k0 + n / D) of conj(FFT(g)).
        G = np.conj(sfft.fft(g, n))
        e = np.abs(G[: n // 2 + 1]) ** 2
        total = float(np.sum(np.abs(G) ** 2))
        c = np.concatenate([[0.0], np.cumsum(e)])
        self.decimation, self._k0 = 1, 0
        for d in DECIMATIONS:
            w = n // d
            if n % d or w > len(e):
                continue
            inside = c[w:] - c[:-w]
            k0 = int(np.argmax(inside))
            if 1.0 - inside[k0] / total <= DECIMATE_TAIL:
                self.decimation, self._k0 = d, k0
                break
        d = self.decimation
        self._g = g
        self._gband = G[self._k0 : self._k0 + n // d].astype(cdt) / d
        self._bands: dict[int, tuple[int, np.ndarray]] = {}
        self.step_dec = self.step - self.step % d
        self._self_response: np.ndarray | None = None

    @property
    def band(self) -> tuple[float, float]:
        """The decimated envelope's band ``[lo, hi)`` in cycles per sample (times ``fs``:
        Hz); the whole rate when :attr:`decimation` is 1."""
        n = self.n_fft
        return self._k0 / n, (self._k0 + n // self.decimation) / n

    @property
    def self_response(self) -> np.ndarray:
        """The filter's output for its own template, centred: index ``len // 2`` is lag 0."""
        if self._self_response is None:
            ref = self
            if self.dtype != "float64":
                ref = MatchedFilter(self.template, block=self.block)
            z = np.zeros(self.n_taps + len(self.template))
            r = ref.correlate(np.concatenate([z, self.template, z]))
            k = len(z)
            self._self_response = r[k - len(z) : k + len(z) + 1].copy()
        return self._self_response

    def _batches(self, x: np.ndarray, lead: int, n_out: int, step: int):
        """Float blocks at the filter's precision, ``(first output lag, blocks)``."""
        rdt = DTYPES[self.dtype][0]
        n = self.n_fft
        per = max(1, (1 << 18) // n)  # blocks per batched FFT call
        n_blocks = -(-n_out // step)
        for b0, win in _block_batches(x, lead, step, n, n_blocks, per):
            yield b0 * step, (win if win.dtype == rdt else win.astype(rdt))

    def _segments(
        self, x: np.ndarray, n_out: int, lead: int = 0, ws: dict | None = None
    ) -> np.ndarray:
        """Correlation outputs ``[0, n_out)`` of ``x`` delayed by ``lead`` zeros.

        The FFT blocks are strided windows of ``x`` (no copies but the padded first and
        last blocks) in batches of about 2^18 samples, small enough that their
        temporaries are reused rather than freshly mapped and zeroed by the OS (see
        ``docs/performance.md``). ``ws``: a workspace dict of the caller's that keeps the
        output and every temporary between calls (the same pocketfft calls scipy makes,
        with their outputs given: the same numbers); the returned array is then the
        workspace's, overwritten by the next call with the same ``ws``.
        """
        if ws is not None and pocketfft() is not None:
            return self._segments_ws(x, n_out, lead, ws)
        sf, n, step = self._fft, self.n_fft, self.step
        out = np.empty(n_out, dtype=DTYPES[self.dtype][1])
        for s0, blocks in self._batches(x, lead, n_out, step):
            X = sf.rfft(blocks, axis=1)
            m = min(n_out - s0, len(blocks) * step)
            full = m // step  # whole blocks: written row by row, no gathered copy
            o2 = out[s0 : s0 + full * step].reshape(full, step)
            for part, g in ((o2.real, self._gr), (o2.imag, self._gi)):
                y = sf.irfft(X * g, n, axis=1)
                part[...] = y[:full, :step]
                if m > full * step:
                    rest = out[s0 + full * step : s0 + m]
                    (rest.real if g is self._gr else rest.imag)[...] = y[full, : m - full * step]
        return out

    def _segments_ws(self, x: np.ndarray, n_out: int, lead: int, ws: dict) -> np.ndarray:
        """:meth:`_segments` with every array kept in ``ws`` (no fresh memory per call)."""
        n, step, pocket = self.n_fft, self.step, pocketfft()
        rdt, cdt = DTYPES[self.dtype]
        out = _ws_array(ws, "out", (n_out,), cdt)
        per = max(1, (1 << 18) // n)
        n_blocks = -(-n_out // step)
        for b0, win in _block_batches(x, lead, step, n, n_blocks, per):
            s0, nb = b0 * step, len(win)
            if win.dtype != rdt:  # as win.astype(rdt), into the workspace
                blocks = _ws_array(ws, "blocks", (nb, n), rdt)
                np.copyto(blocks, win, casting="unsafe")
                win = blocks
            X = pocket.r2c(win, (1,), True, 0, _ws_array(ws, "X", (nb, n // 2 + 1), cdt), 1)
            prod = _ws_array(ws, "prod", X.shape, cdt)
            y = _ws_array(ws, "y", (nb, n), rdt)
            m = min(n_out - s0, nb * step)
            full = m // step
            o2 = out[s0 : s0 + full * step].reshape(full, step)
            for part, g in ((o2.real, self._gr), (o2.imag, self._gi)):
                np.multiply(X, g, out=prod)
                pocket.c2r(prod, (1,), n, False, 2, y, 1)
                part[...] = y[:full, :step]
                if m > full * step:
                    rest = out[s0 + full * step : s0 + m]
                    (rest.real if g is self._gr else rest.imag)[...] = y[full, : m - full * step]
        return out

    def _envelope_segments(self, x: np.ndarray, n_out: int, lead: int = 0) -> np.ndarray:
        """``|correlation|`` at lags ``0, D, 2D, ...`` below ``n_out`` (complex baseband)."""
        sf, n, d = self._fft, self.n_fft, self.decimation
        step = self.step_dec
        k0, w = self._k0, n // d
        n_dec = -(-n_out // d)
        out = np.empty(n_dec, dtype=DTYPES[self.dtype][0])
        per_block = step // d
        for s0, blocks in self._batches(x, lead, n_out, step):
            X = sf.rfft(blocks, axis=1)
            y = sf.ifft(X[:, k0 : k0 + w] * self._gband, axis=1)[:, :per_block]
            j0 = s0 // d
            m = min(n_dec - j0, len(blocks) * per_block)
            out[j0 : j0 + m] = np.abs(y.reshape(-1)[:m])
        return out

    def correlate(self, x: np.ndarray) -> np.ndarray:
        """Analytic correlation of the whole of ``x`` (complex, same length as ``x``)."""
        x = _check_x("x", x)
        return self._segments(x, len(x), lead=self.pre)

    def envelope(self, x: np.ndarray) -> np.ndarray:
        """The envelope ``|correlate(x)|`` at the lags ``0, D, 2D, ...`` (``D`` =
        :attr:`decimation`), at the filter's precision.

        Equal to ``np.abs(correlate(x))[::D]`` to within ``sqrt(DECIMATE_TAIL)`` of the
        output's RMS (the FIR's energy outside the band; tested), at about a third of
        the cost for ``D = 4``.
        """
        x = _check_x("x", x)
        if self.decimation == 1:  # a broadband template: no band to cut (exact)
            return np.abs(self._segments(x, len(x), lead=self.pre))
        return self._envelope_segments(x, len(x), lead=self.pre)

    def _band_at(self, n: int) -> tuple[int, np.ndarray]:
        """The decimated band's first bin and filter spectrum on an ``n``-point grid."""
        hit = self._bands.get(n)
        if hit is None:
            d = self.decimation
            k0 = int(round(self._k0 * n / self.n_fft))
            G = np.conj(self._fft.fft(self._g, n))
            hit = self._bands[n] = (k0, G[k0 : k0 + n // d].astype(DTYPES[self.dtype][1]) / d)
        return hit

    def _span_pieces(self, x: np.ndarray, sp: np.ndarray, align: int):
        """The inputs of the spans laid end to end (each with the template's reach),
        every piece starting at a multiple of ``align``; and their offsets."""
        n = len(x)
        pieces, offsets, total = [], [], 0
        for a, b in sp.tolist():
            if not 0 <= a <= b <= n:
                raise InvalidParameterError(f"span [{a}, {b}) is not within [0, {n}]")
            lo, hi = a - self.pre, b - self.pre + self.n_taps
            hi += -(hi - lo) % align
            piece = x[max(lo, 0) : min(hi, n)]
            if lo < 0 or hi > n:
                pad = (np.zeros(max(0, -lo), x.dtype), np.zeros(max(0, hi - n), x.dtype))
                piece = np.concatenate([pad[0], piece, pad[1]])
            pieces.append(piece)
            offsets.append(total)
            total += len(piece)
        return (np.concatenate(pieces) if pieces else np.zeros(0, x.dtype)), offsets, total

    def correlate_spans(self, x: np.ndarray, spans: np.ndarray) -> list[np.ndarray]:
        """Analytic correlation at the lags ``[a, b)`` of each span only.

        Equal to ``correlate(x)[a:b]`` for every row ``(a, b)`` of ``spans`` (``0 <= a <=
        b <= len(x)``), at the cost of the spans' total length rather than the whole
        signal's: the spans' inputs (each with the template's reach) are laid end to end
        and correlated by the same overlap-save blocks; outputs that would straddle two
        pieces are never read.
        """
        return self._correlate_spans(_check_x("x", x), spans)

    def _correlate_spans(self, x: np.ndarray, spans: np.ndarray) -> list[np.ndarray]:
        sp = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
        if len(sp) == 0:
            return []
        cat, offsets, total = self._span_pieces(x, sp, 1)
        out = self._segments(cat, total)
        return [out[o : o + (b - a)] for o, (a, b) in zip(offsets, sp.tolist(), strict=True)]

    def envelope_spans(self, x: np.ndarray, spans: np.ndarray) -> list[np.ndarray]:
        """:meth:`envelope` at the lags ``a, a + D, ...`` below ``b`` of each span."""
        return self._envelope_spans(_check_x("x", x), spans)

    def _envelope_spans(self, x: np.ndarray, spans: np.ndarray) -> list[np.ndarray]:
        """Each span on its own FFT grid (its result depends on its samples only, not
        on where it lies in ``x`` or on the other spans); spans of one grid size batched."""
        if self.decimation == 1:  # a broadband template: no band to cut (exact)
            return [np.abs(c) for c in self._correlate_spans(x, spans)]
        sp = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
        d, sf = self.decimation, self._fft
        rdt = DTYPES[self.dtype][0]
        out: list = [None] * len(sp)
        by_size: dict[int, list[int]] = {}
        for i, (a, b) in enumerate(sp.tolist()):
            if not 0 <= a <= b <= len(x):
                raise InvalidParameterError(f"span [{a}, {b}) is not within [0, {len(x)}]")
            n_in = b - a + self.n_taps
            n = max(1 << int(math.ceil(math.log2(n_in))), 4 * d)
            if n > self.n_fft:  # long: overlap-save blocks from the span's own start
                piece, _, total = self._span_pieces(x, sp[i : i + 1], d)
                out[i] = self._envelope_segments(piece, total)[: -(-(b - a) // d)]
            else:
                by_size.setdefault(n, []).append(i)
        for n, idx in by_size.items():
            k0, gb = self._band_at(n)
            rows = max(1, (1 << 18) // n)  # spans per batched FFT call
            for j in range(0, len(idx), rows):
                part = idx[j : j + rows]
                buf = np.zeros((len(part), n), dtype=rdt)
                for r, i in enumerate(part):
                    a, b = (int(v) for v in sp[i])
                    lo, hi = a - self.pre, b - self.pre + self.n_taps
                    s0, s1 = max(lo, 0), min(hi, len(x))
                    buf[r, s0 - lo : s1 - lo] = x[s0:s1]
                X = sf.rfft(buf, axis=1)
                env = np.abs(sf.ifft(X[:, k0 : k0 + n // d] * gb, axis=1))
                for r, i in enumerate(part):
                    a, b = (int(v) for v in sp[i])
                    out[i] = env[r, : -(-(b - a) // d)]
        return out

    def stream(self, chunks: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
        """Correlate a signal given as consecutive chunks; yields output chunks in order.

        The outputs concatenated equal :meth:`correlate` of the concatenated input (bit
        for bit); memory is bounded by the chunk size plus :data:`STREAM_MIN_BLOCKS` FFT
        blocks. Each output chunk lags its input by the template length (the correlation
        needs that much look-ahead) plus up to ``STREAM_MIN_BLOCKS`` overlap-save steps:
        only whole steps are computed, at least that many per FFT call (cheaper per
        block, :data:`STREAM_MIN_BLOCKS`), the rest is carried over to the next chunk.
        """
        rdt = DTYPES[self.dtype][0]
        pending = [np.zeros(self.pre, dtype=rdt)]  # input not yet correlated, in order
        done = 0  # outputs emitted so far
        seen = 0  # input samples seen so far
        look = self.n_taps - self.pre
        min_ready = STREAM_MIN_BLOCKS * self.step
        for chunk in chunks:
            c = _check_x("chunk", chunk)
            pending.append(np.array(c, dtype=rdt))  # a copy: the caller may reuse chunk
            seen += len(c)
            ready = seen - look - done
            ready -= ready % self.step  # whole steps only: no partly used FFT block
            if ready >= min_ready:
                buf = np.concatenate(pending)
                yield self._segments(buf, ready)
                done += ready
                pending = [buf[ready:]]
        tail = seen - done
        if tail > 0:
            yield self._segments(np.concatenate(pending), tail)


#: Weightings of the matched filter's cross spectrum (:func:`weighting_response`).
WEIGHTINGS = ("none", "prewhiten", "phat", "scot", "ml")
#: Regularisation of the noise-spectrum weights: a band is never weighted more than
#: 1 / NOISE_WEIGHT_REG (+20 dB) above the band's median noise level.
NOISE_WEIGHT_REG = 1e-2


@dataclass(frozen=True)
class Spectra:
    """Welch power spectral densities of one recording (one-sided, per Hz).

    Attributes
    ----------
    f_hz : ndarray, shape (nperseg // 2 + 1,)
        Frequencies of the bins, Hz.
    noise : ndarray
        Noise PSD: the median over segments (divided by ln 2, the median of an
        exponential variable in units of its mean), robust to arrivals that occupy a
        minority of the segments at each frequency.
    mean : ndarray
        Mean PSD over the same segments (noise and signal).
    nperseg : int
        Segment length, samples (the weights' frequency resolution is ``fs / nperseg``).
    """

    f_hz: np.ndarray
    noise: np.ndarray
    mean: np.ndarray
    nperseg: int


def welch_spectra(
    x: np.ndarray,
    *,
    fs: float,
    nperseg: int,
    max_segments: int = 256,
    min_segments: int = 32,
    q: float = 20.0,
    rel_zero: float = 1e-18,
) -> Spectra:
    """Noise and mean PSD of ``x`` from Hann-windowed, non-overlapping segments.

    Welch (1967) averaging, with a low percentile across segments for the noise (the
    idea of ``scipy.signal.welch(..., average="median")``, more robust): a sweep holds
    any one frequency for a few milliseconds, a tone burst is on for a small fraction of
    the recording, so at each frequency most segments hold noise only. The ``q``-th
    percentile of the segments' periodograms, divided by ``-ln(1 - q / 100)`` (the mean
    of an exponential variable, the law of one bin of noise, whose ``q``-th percentile it
    is), stays the noise level while arrivals occupy up to about ``1 - q / 100`` of the
    segments at a frequency. Segments of digital silence (energy at or below ``rel_zero``
    times the largest segment's) are left out, so zero padding does not pull the noise to
    zero. Long recordings are represented by ``max_segments`` segments spread evenly over
    them; short ones use shorter segments (down to 128 samples) to have at least
    ``min_segments``. Scaled so that ``sum(psd) * fs / nperseg`` is the mean power
    (Parseval).

    Parameters
    ----------
    x : ndarray
        The recording (one channel).
    fs : float
        Sample rate, Hz.
    nperseg : int
        Segment length, samples (the longest used).
    max_segments, min_segments : int
        Most segments used (evenly spaced); fewest wanted before shortening segments.
    q : float
        Percentile of the noise estimate.
    rel_zero : float
        Relative energy at or below which a segment counts as digital silence (default 1e-18,
        -180 dB: exact zeros and rounding residue, never a quiet noise floor).

    Returns
    -------
    Spectra
        ``nperseg`` is the segment length actually used; ``noise`` and ``mean`` are
        zeros when fewer than 8 segments hold signal.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(100000)
    >>> s = welch_spectra(x, fs=1000.0, nperseg=256)
    >>> bool(abs(np.median(s.noise) * 500.0 - 1.0) < 0.1)
    True
    """
    from scipy.signal import get_window

    fs = V.sample_rate(fs)
    x = np.asarray(x, dtype=np.float64)
    nperseg = V.positive_int("nperseg", nperseg, minimum=8)
    while nperseg > 128 and len(x) // nperseg < min_segments:
        nperseg //= 2
    nb = nperseg // 2 + 1
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)
    empty = Spectra(f, np.zeros(nb), np.zeros(nb), nperseg)
    n_seg = len(x) // nperseg
    if n_seg < 8:
        return empty
    starts = np.arange(n_seg) * nperseg
    if n_seg > max_segments:
        starts = starts[np.linspace(0, n_seg - 1, max_segments).round().astype(np.int64)]
    segs = x[starts[:, None] + np.arange(nperseg)]
    e = np.einsum("ij,ij->i", segs, segs)
    live = e > rel_zero * float(e.max()) if e.max() > 0 else np.zeros(len(e), bool)
    if live.sum() < 8:
        return empty
    w = get_window("hann", nperseg)
    P = np.abs(np.fft.rfft(segs[live] * w, axis=1)) ** 2
    P *= 2.0 / (fs * float(w @ w))
    P[:, 0] *= 0.5
    if nperseg % 2 == 0:
        P[:, -1] *= 0.5
    mean = P.mean(axis=0)
    k = int(round(q / 100.0 * (len(P) - 1)))
    noise = np.partition(P, k, axis=0)[k] / -math.log(1.0 - q / 100.0)
    return Spectra(f, noise, mean, nperseg)


def common_spectra(spectra: Sequence[Spectra]) -> Spectra:
    """One noise spectrum for several recordings: the bin-wise maximum.

    Weighting every device of an exchange by the same spectrum keeps the weighting's
    share of the transducers' dispersion in the onsets the same for all of them, so it
    cancels in two-way ranging (``docs/theory/probes.md``). The spectra must share
    their grid (same rate and segment length).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> a = welch_spectra(rng.standard_normal(20000), fs=1000.0, nperseg=128)
    >>> b = welch_spectra(3 * rng.standard_normal(20000), fs=1000.0, nperseg=128)
    >>> bool(np.all(common_spectra([a, b]).noise == np.maximum(a.noise, b.noise)))
    True
    """
    spectra = list(spectra)
    if not spectra:
        raise InvalidParameterError("common_spectra needs at least one Spectra")
    f = spectra[0].f_hz
    for sp in spectra[1:]:
        if len(sp.f_hz) != len(f) or not np.allclose(sp.f_hz, f):
            raise InvalidParameterError(
                "spectra must share their frequency grid (same rate and segment length)"
            )
    noise = np.max([sp.noise for sp in spectra], axis=0)
    mean = np.max([sp.mean for sp in spectra], axis=0)
    return Spectra(f, noise, mean, spectra[0].nperseg)


def weighting_response(
    kind: str,
    spectra: Spectra,
    *,
    template_psd: np.ndarray,
    band_hz: tuple[float, float],
) -> np.ndarray | None:
    """Real, non-negative weight ``W(f)`` of the matched filter's cross spectrum.

    The weighted matched filter correlates ``x`` with the template through
    ``X(f) W(f) S*(f)`` (``S``: the template's spectrum). The generalised
    cross-correlation (GCC) weightings of Knapp & Carter (1976, "The generalized
    correlation method for estimation of time delay", IEEE Trans. ASSP 24(4), Table I),
    written for a *known* noise-free template (``G_ss = |S|^2``, the template's noise is
    zero):

    * ``"none"``: ``W = 1``, the plain matched filter (optimal in white noise).
    * ``"prewhiten"``: ``W = 1 / sqrt(N)``: the recording whitened by its noise PSD ``N``,
      correlated with the unwhitened template.
    * ``"phat"``: ``W = 1 / |G_xs| ~ 1 / |S|^2``: the phase transform; with a known
      template its expected cross spectrum is ``|S|^2``, so PHAT is inverse filtering
      within the band, whatever the noise.
    * ``"scot"``: ``W = 1 / sqrt(G_xx G_ss) = 1 / (|S| sqrt(G_xx))``, ``G_xx`` the
      recording's mean PSD (noise and signal).
    * ``"ml"``: ``W = 1 / N``: the maximum-likelihood (Hannan & Thomson; Eckart's filter
      ``|S|^2 / (N_1 N_2)`` with the template's noise zero) matched filter in coloured
      noise, ``S*(f) / N(f)``: both recording and template prewhitened (Van Trees 1968,
      *Detection, Estimation and Modulation Theory I*, §4.3).

    ``N`` is regularised as ``N + NOISE_WEIGHT_REG * median_band(N)`` (no band is weighted
    more than +20 dB above the band's median noise), ``|S|^2`` likewise relative to its
    maximum; ``W`` is normalised to a median of 1 over ``band_hz``.

    Returns
    -------
    ndarray or None
        ``W`` on ``spectra.f_hz``; None for ``"none"`` or when the recording holds no
        noise to weight by (digital silence).
    """
    if kind not in WEIGHTINGS:
        raise InvalidParameterError(f"weighting={kind!r} must be one of {', '.join(WEIGHTINGS)}")
    if kind == "none":
        return None
    f = spectra.f_hz
    if len(template_psd) != len(f):  # shorter segments were used: the same grid, coarser
        fine = np.linspace(0.0, f[-1], len(template_psd))
        template_psd = np.interp(f, fine, template_psd)
    band = (f >= band_hz[0]) & (f <= band_hz[1])
    if not band.any():
        band = np.ones(len(f), bool)
    S2 = np.asarray(template_psd, dtype=np.float64)
    S2 = S2 + NOISE_WEIGHT_REG * float(S2.max())

    def reg(p: np.ndarray) -> np.ndarray | None:
        m = float(np.median(p[band]))
        if not m > 0:
            return None
        # Smoothed over 5 bins (in dB): a noise spectrum's broad shape is what is
        # weighted; the periodograms' scatter and a sweep's Fresnel ripple are not (their
        # weights' FIR would ring into echoes of every strong arrival).
        lp = np.log(p + NOISE_WEIGHT_REG * m)
        lp = np.convolve(np.pad(lp, 2, mode="edge"), np.full(5, 0.2), mode="valid")
        return np.exp(lp)

    if kind == "phat":
        W = 1.0 / S2
    else:
        N = reg(spectra.mean if kind == "scot" else spectra.noise)
        if N is None:
            return None
        W = {"prewhiten": lambda: 1.0 / np.sqrt(N), "ml": lambda: 1.0 / N}.get(
            kind, lambda: 1.0 / np.sqrt(N * S2)
        )()
    return W / float(np.median(W[band]))


def zero_phase_taps(W: np.ndarray, nperseg: int) -> np.ndarray:
    """Symmetric FIR (odd length ``nperseg - 1``) whose response is ``W`` smoothed.

    ``W`` on ``rfftfreq(nperseg)``: its inverse FFT, centred, Hann-windowed (the response
    is ``W`` convolved with the window's kernel, two bins wide). Real and even in
    frequency, so applied with its group delay removed it moves no arrival.
    """
    from scipy.signal import get_window

    w = np.fft.irfft(np.asarray(W, dtype=np.float64), nperseg)
    w = np.roll(w, nperseg // 2)[1:]
    taps = w * get_window("hann", len(w), fftbins=False)
    return np.ascontiguousarray(0.5 * (taps + taps[::-1]))


def noise_level(env: np.ndarray) -> float:
    """Rayleigh scale of the envelope's noise, from its median (robust to the signal)."""
    if len(env) == 0:
        return 0.0
    return float(np.median(env)) / _RAYLEIGH_MEDIAN


def interp_peak(env: np.ndarray, i: int) -> tuple[float, float]:
    """Sub-sample offset and height of the envelope peak at integer index ``i``.

    A parabola through ``log(env)`` at ``i - 1, i, i + 1`` (a Gaussian fit); the offset is
    clipped to [-0.5, 0.5]. At the ends of the array the offset is 0.

    Examples
    --------
    >>> n = np.arange(40.0)
    >>> env = np.exp(-0.5 * ((n - 20.3) / 4.0) ** 2)
    >>> [round(v, 9) for v in interp_peak(env, 20)]
    [0.3, 1.0]
    """
    if i <= 0 or i >= len(env) - 1:
        return 0.0, float(env[i])
    a, b, c = (float(v) for v in env[i - 1 : i + 2])
    if min(a, b, c) <= 0.0:
        return 0.0, b
    la, lb, lc = math.log(a), math.log(b), math.log(c)
    den = la - 2.0 * lb + lc
    if den >= 0.0:
        return 0.0, b
    d = min(0.5, max(-0.5, 0.5 * (la - lc) / den))
    return d, math.exp(lb - 0.25 * (la - lc) * d)


@dataclass(frozen=True)
class PathPeak:
    """The chosen path of one matched-filter window.

    Attributes
    ----------
    lag : float
        Sub-sample lag of the path in samples from the window's start.
    height : float
        Envelope height at the peak.
    snr : float
        Peak height over the noise's Rayleigh scale (``sqrt(2 E / N0)``, linear).
    strongest_lag : float
        Lag of the strongest peak in the window (equals ``lag`` unless an earlier path won).
    """

    lag: float
    height: float
    snr: float
    strongest_lag: float


def first_path(
    c: np.ndarray,
    *,
    lo: int = 0,
    hi: int | None = None,
    noise: float | None = None,
    k_noise: float = DEFAULT_K_NOISE,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    k_detect: float = DEFAULT_K_DETECT,
    self_response: np.ndarray | None = None,
    n_paths: int = 1,
    env: np.ndarray | None = None,
) -> PathPeak | None:
    """The earliest envelope peak above ``max(k_noise * noise, rel_threshold * strongest)``.

    Nothing is detected unless the strongest peak clears ``k_detect * noise``. An earlier
    peak replaces the strongest only if it clears the (higher) first-path threshold; when
    none does, the strongest peak is the path.

    Parameters
    ----------
    c : ndarray
        Analytic matched-filter output (complex), or its envelope (real, >= 0).
    lo, hi : int
        Search only lags in ``[lo, hi)`` (default the whole array).
    noise : float, optional
        Rayleigh scale of the noise envelope; default :func:`noise_level` of ``|c|``.
    k_noise : float
        Noise multiple of the first-path threshold (default 6).
    rel_threshold : float
        Fraction of the strongest peak in ``[lo, hi)`` (default 0.25, -12 dB).
    k_detect : float
        Noise multiple the strongest peak must clear (default 4.5).
    self_response : ndarray, optional
        The filter's complex response to its own template, centred (index
        ``len // 2`` = lag 0; :attr:`MatchedFilter.self_response`). With it (and complex
        ``c``), a candidate earlier than the strongest peak must still clear the threshold
        after the strongest path's own side lobes are subtracted, so a side lobe of a strong
        reflection is not taken for the direct path.
    n_paths : int
        With ``self_response``: a candidate must also clear the threshold after the
        responses of up to ``n_paths`` stronger peaks that follow it within the self
        response's reach are fitted jointly (complex least squares at their peaks) and
        subtracted, a few steps of CLEAN (Högbom 1974, "Aperture synthesis with a
        non-regular distribution of interferometer baselines", A&AS 15): in a room the
        direct path's own side lobes, not only the strongest path's, precede it.
        Default 1: the strongest path only.
    env : ndarray, optional
        ``np.abs(c)`` when the caller has it already (not computed again).

    Returns
    -------
    PathPeak or None
        None when nothing in the search range clears the threshold.
    """
    env = np.abs(c) if env is None else env
    hi = len(env) if hi is None else min(int(hi), len(env))
    lo = max(0, int(lo))
    if hi - lo < 3:
        return None
    seg = env[lo:hi]
    noise = noise_level(env) if noise is None else float(noise)
    # Local maxima only (neighbours outside [lo, hi) count), so that the falling slope of
    # something before the search range (e.g. a ring-down) is never taken for a path.
    left = env[lo - 1 : hi - 1] if lo > 0 else np.concatenate([[-np.inf], env[: hi - 1]])
    right = env[lo + 1 : hi + 1]
    if len(right) < len(seg):
        right = np.concatenate([right, [-np.inf]])
    peaks = np.flatnonzero((seg >= left) & (seg > right))
    if len(peaks) == 0:
        return None
    # An absolute floor: a noiseless (synthetic) signal must not make rounding noise count.
    noise = max(noise, NOISE_FLOOR_REL * float(env.max()))
    if self_response is not None and np.iscomplexobj(c):
        peaks = _drop_outside_sidelobes(c, env, peaks, lo, hi, k_detect * noise, self_response)
        if len(peaks) == 0:
            return None
    imax = int(peaks[np.argmax(seg[peaks])])
    top = float(seg[imax])
    thr = max(k_noise * noise, rel_threshold * top)
    if top <= k_detect * noise or top <= 0.0:
        return None
    dmax, _ = interp_peak(env, lo + imax)
    # Local maxima above the threshold before the strongest one, earliest first.
    cand = peaks[(peaks < imax) & (seg[peaks] >= thr)]
    j = imax
    resid = None
    if len(cand) and self_response is not None and np.iscomplexobj(c):
        resid = _sidelobe_residual(c, lo + imax, dmax, self_response)
    for k in cand:
        if resid is None or abs(resid(lo + int(k))) >= thr:
            if n_paths > 1 and self_response is not None and np.iscomplexobj(c):
                later = lo + peaks[(peaks > k) & (seg[peaks] > seg[k])]
                if not _clears_later_paths(c, env, lo + int(k), later, thr, self_response,
                                           n_paths):  # fmt: skip
                    continue
            j = int(k)
            break
    d, h = interp_peak(env, lo + j)
    snr = h / noise if noise > 0 else math.inf
    return PathPeak(lo + j + d, h, snr, lo + imax + dmax)


def _drop_outside_sidelobes(
    c: np.ndarray,
    env: np.ndarray,
    peaks: np.ndarray,
    lo: int,
    hi: int,
    floor: float,
    self_response: np.ndarray,
) -> np.ndarray:
    """Drop in-range peaks that are only side lobes of a stronger path just outside.

    A path just before ``lo`` (or after ``hi``) spreads side lobes into the search range;
    those peaks are kept only if they still clear ``floor`` once that path's own response
    is subtracted.
    """
    m = len(self_response) // 2
    top = float(env[lo + peaks].max())
    for a, b in ((max(1, lo - m), lo), (hi, min(len(env) - 1, hi + m))):
        if b <= a:
            continue
        w = env[a:b]
        pk = np.flatnonzero((w >= env[a - 1 : b - 1]) & (w > env[a + 1 : b + 1]))
        if len(pk) == 0:
            continue
        j = a + int(pk[np.argmax(w[pk])])
        if env[j] <= top:
            continue
        d, _ = interp_peak(env, j)
        resid = _sidelobe_residual(c, j, d, self_response)
        peaks = np.array([p for p in peaks if abs(resid(lo + int(p))) >= floor], dtype=np.int64)
    return peaks


def _clears_later_paths(
    c: np.ndarray,
    env: np.ndarray,
    k: int,
    later: np.ndarray,
    thr: float,
    self_response: np.ndarray,
    n_paths: int,
) -> bool:
    """Whether ``c[k]`` stays above ``thr`` once the stronger later paths are removed.

    The ``n_paths`` strongest peaks in ``later`` within the self response's reach of
    ``k`` are modelled as paths at their sub-sample lags; their amplitudes solve the
    square system ``c[j_i] = sum_l alpha_l R(j_i - tau_l)``.
    """
    m = len(self_response) // 2
    later = later[(later - k < m) & (later < len(c))]
    if len(later) == 0:
        return True
    later = later[np.argsort(-env[later], kind="stable")[:n_paths]]
    n = len(self_response)
    f = np.fft.fftfreq(n)
    spec = np.fft.fft(self_response)
    shifted, pos = [], []
    for j in later.tolist():
        d, _ = interp_peak(env, j)
        shifted.append(np.fft.ifft(spec * np.exp(-2j * math.pi * f * d)))
        pos.append(j)

    def resp(p: int, at: int) -> complex:
        i = at - pos[p] + m
        return complex(shifted[p][i]) if 0 <= i < n else 0.0

    A = np.array([[resp(p, at) for p in range(len(pos))] for at in pos])
    try:
        alpha = np.linalg.solve(A, c[np.array(pos)])
    except np.linalg.LinAlgError:
        return True
    model = sum(alpha[p] * resp(p, k) for p in range(len(pos)))
    return abs(c[k] - model) >= thr


def _sidelobe_residual(c: np.ndarray, i_peak: int, d_peak: float, self_response: np.ndarray):
    """``f(i) = c[i] - (the strongest path's own response at lag i)``.

    The path at sub-sample lag ``i_peak + d_peak`` contributes ``alpha R(i - i_peak -
    d_peak)`` with ``R`` the filter's self response (band-limited, so shifted by ``d_peak``
    exactly in the frequency domain) and ``alpha`` fitted at ``i_peak``.
    """
    n = len(self_response)
    mid = n // 2
    f = np.fft.fftfreq(n)
    shifted = np.fft.ifft(np.fft.fft(self_response) * np.exp(-2j * math.pi * f * d_peak))
    alpha = c[i_peak] / shifted[mid]

    def resid(i: int) -> complex:
        k = i - i_peak + mid
        model = alpha * shifted[k] if 0 <= k < n else 0.0
        return complex(c[i] - model)

    return resid


def crb_delay_s(
    signal: np.ndarray, *, fs: float, noise_sigma: float, coherent: bool = False
) -> float:
    """Cramér–Rao bound (1-sigma, seconds) on the delay of a known waveform in white noise.

    The model is ``x[n] = A s(n / fs - tau; phi) + w[n]`` with ``w`` white Gaussian of
    standard deviation ``noise_sigma`` per sample and ``signal`` the noiseless received
    waveform (amplitude included). With ``coherent=False`` the amplitude ``A`` and the
    carrier phase ``phi`` (``s = Re{s_a e^{j phi}}``) are unknown nuisance parameters and the
    bound is ``[J^-1]_tau_tau`` of the 3x3 Fisher matrix; for a symmetric envelope it is
    ``1 / (2 pi beta sqrt(2 E / N0))`` with ``beta`` the RMS bandwidth about the
    centre. With ``coherent=True`` only the delay is unknown: ``1 / (2 pi beta_0
    sqrt(2 E / N0))`` with Gabor's bandwidth ``beta_0`` (about 0 Hz).

    Examples
    --------
    >>> fs = 192000.0
    >>> h = coded_template(CodedBurst(), fs=fs)
    >>> b = rms_bandwidth_hz(h, fs=fs)
    >>> snr = math.sqrt(h @ h) / 0.01
    >>> ratio = crb_delay_s(h, fs=fs, noise_sigma=0.01) * 2 * math.pi * b * snr
    >>> bool(0.98 < ratio < 1.1)
    True

    See Also
    --------
    rangekit.signals.spectrum.rms_bandwidth_hz
    """
    fs = V.sample_rate(fs)
    s = V.signal_1d("signal", signal)
    sigma = V.positive("noise_sigma", noise_sigma)
    n = 1 << int(math.ceil(math.log2(4 * len(s) + 8)))
    spec = np.fft.fft(s, n)
    f = np.fft.fftfreq(n, 1.0 / fs)
    ds = np.fft.ifft(-2j * math.pi * f * spec).real  # d s(t - tau) / d tau
    if coherent:
        return sigma / math.sqrt(float(ds @ ds))
    sa_spec = spec.copy()
    sa_spec[f < 0] = 0.0
    sa_spec[f > 0] *= 2.0
    sa = np.fft.ifft(sa_spec)
    d_phi = -sa.imag  # d/dphi Re{s_a e^{j phi}} at phi = 0
    d_amp = np.concatenate([s, np.zeros(n - len(s))])
    d = np.stack([ds, d_amp, d_phi])
    J = d @ d.T / sigma**2
    return math.sqrt(float(np.linalg.inv(J)[0, 0]))


#: Lags each side of a window's search range whose envelope the first-path rule reads
#: beyond the self response's reach.
_SPAN_PAD = 2
#: Fewest envelope samples the noise level of a window is estimated from (the search range
#: is widened within the window to this many where it is shorter).
NOISE_MIN_SPAN = 8192
#: Fewest samples before an arrival its fit's noise level is taken from.
NOISE_MIN_PRE = 512
#: An arrival below this many times ``k_detect`` noise scales is flagged ``low_snr``
#: (13.5, 22.6 dB: below it a direct path 3.5 dB weaker than the chosen one, e.g. the
#: 1.5x reflection of a ceiling bounce taken for the first path, is within 2 noise
#: scales of the first-path threshold ``k_noise`` and may have been missed).
LOW_SNR_FACTOR = 3.0
#: ``poor_match`` when the fitted model leaves this fraction of the arrival's energy
#: unexplained (beyond the noise), with the excess ``POOR_MATCH_Z`` deviations up.
POOR_MATCH_MISFIT = 0.05
POOR_MATCH_Z = 5.0
#: The fitted model's misfit counts in sigma beyond this many deviations of the noise.
MISFIT_Z_FREE = 3.0
#: ``ambiguous_first_path`` when a stronger path follows the first one within this many
#: times the model's resolution (half width of its autocorrelation envelope at one half).
AMBIGUOUS_RESOLUTIONS = 1.0


@functools.lru_cache(maxsize=8)
def _cached_filter(key: bytes, n: int, block: int, dtype: str) -> MatchedFilter:
    h = np.frombuffer(key, dtype=np.float64, count=n)
    return MatchedFilter(h, block=block, dtype=dtype)


def matched_filter(
    template: np.ndarray, *, block: int = DEFAULT_BLOCK, dtype: str = "float64"
) -> MatchedFilter:
    """A :class:`MatchedFilter` of ``template``, shared between calls with equal templates."""
    h = np.ascontiguousarray(V.signal_1d("template", template), dtype=np.float64)
    return _cached_filter(h.tobytes(), len(h), int(block), dtype)


def _window_correlations(
    x: np.ndarray, template: np.ndarray, spans: np.ndarray, *, block: int = DEFAULT_BLOCK
) -> _WindowCorrelations:
    """Per span ``[a, b)`` (``x`` as :func:`_check_x` returns it): the exact analytic
    correlation, its envelope's Rayleigh noise scale and the envelope, from one
    correlation per window (:class:`_WindowCorrelations`: indexable, computed a chunk of
    windows at a time).

    The noise is the median of the full-rate float64 envelope on purpose: the median of
    the decimated float32 envelope (:meth:`MatchedFilter.envelope`, every ``D``-th lag) is
    a different estimate of the same scale (0.4 % apart on the bench's windows), and it
    moved accuracy rows (``oneway_accuracy --model bandpass --snr 10``, Q 4: RMS 7.83 ->
    7.36 mm; ``docs/performance.md``), which the speed-up must not do.
    """
    return _WindowCorrelations(matched_filter(template, block=block), x, spans)


#: Output lags (about; at least one span) :class:`_WindowCorrelations` computes at a time:
#: 4 MB of complex output, which the allocator reuses from chunk to chunk (a whole
#: recording's spans at once, 0.42 GB for the one-way bench's 10 minutes, cost 1.06 s of
#: page faults alone on this machine, three times the FFTs; ``docs/performance.md``).
WINDOW_CHUNK = 1 << 18


class _WindowCorrelations:
    """``[i] -> (c, noise, env)`` of span ``i``: the analytic correlation at its lags
    (``correlate(x)[a:b]``), its envelope's Rayleigh noise scale and the envelope ``|c|``.

    Bit for bit what :meth:`MatchedFilter._correlate_spans` of all spans gives (the same
    end-to-end layout of the spans' inputs, the same overlap-save blocks), but computed a
    chunk of about ``WINDOW_CHUNK`` output lags at a time when a span is first asked for,
    so that the whole recording's correlation is never held (the last chunk is kept:
    windows are read in order). The arrays of a chunk live in one reused workspace: a
    span's ``c`` is overwritten when another chunk is computed (use it, or copy it,
    before asking for a span of another chunk).
    """

    def __init__(self, mf: MatchedFilter, x: np.ndarray, spans: np.ndarray) -> None:
        sp = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
        n = len(x)
        bad = np.flatnonzero((sp[:, 0] < 0) | (sp[:, 0] > sp[:, 1]) | (sp[:, 1] > n))
        if len(bad):
            i = int(bad[0])
            raise InvalidParameterError(f"span [{sp[i, 0]}, {sp[i, 1]}) is not within [0, {n}]")
        self.mf, self.x, self.sp = mf, x, sp
        # Each span's input x[a - pre, b - pre + n_taps) (zeros outside x), end to end.
        self.lo = sp[:, 0] - mf.pre
        self.length = sp[:, 1] - sp[:, 0] + mf.n_taps
        self.offsets = np.concatenate([[0], np.cumsum(self.length)]).astype(np.int64)
        self._chunk: tuple[int, int, list] | None = None
        self._ws: dict = {}  # the chunks' output and temporaries, reused

    def __len__(self) -> int:
        return len(self.sp)

    def __getitem__(self, i: int) -> tuple[np.ndarray, float, np.ndarray]:
        i = int(i)
        if not 0 <= i < len(self.sp):
            raise IndexError(i)
        ch = self._chunk
        if ch is None or not ch[0] <= i < ch[1]:
            ch = self._chunk = self._compute(i)
        return ch[2][i - ch[0]]

    def _compute(self, i: int) -> tuple[int, int, list]:
        """Spans ``i, i + 1, ...`` (about ``WINDOW_CHUNK`` output lags) at once."""
        mf, off, step = self.mf, self.offsets, self.mf.step
        # Whole global blocks from the one holding span i's first output: block k of this
        # call reads the same samples as block g0 / step + k of the whole layout.
        g0 = (int(off[i]) // step) * step
        j = i + 1
        while j < len(self.sp) and off[j] + self.sp[j, 1] - self.sp[j, 0] - g0 <= WINDOW_CHUNK:
            j += 1
        n_out = int(off[j - 1] + self.sp[j - 1, 1] - self.sp[j - 1, 0]) - g0
        n_blocks = -(-n_out // step)
        g1 = min(int(off[-1]), g0 + (n_blocks - 1) * step + mf.n_fft)
        out = mf._segments(self._inputs(g0, g1), n_out, ws=self._ws)
        res = []
        for k in range(i, j):
            o = int(off[k]) - g0
            c = out[o : o + int(self.sp[k, 1] - self.sp[k, 0])]
            env = np.abs(c)
            # noise_level(env) (c is finite: x is checked), by one partition.
            noise = _median(env) / _RAYLEIGH_MEDIAN if len(env) else 0.0
            res.append((c, noise, env))
        return i, j, res

    def _inputs(self, g0: int, g1: int) -> np.ndarray:
        """The end-to-end layout of the spans' inputs at ``[g0, g1)``."""
        x, n = self.x, len(self.x)
        buf = _ws_array(self._ws, "in", (max(g1 - g0, 0),), x.dtype)
        buf[...] = 0.0
        off = self.offsets
        k = max(0, int(np.searchsorted(off, g0, side="right")) - 1)
        while k < len(self.sp) and off[k] < g1:
            p0, p1 = max(int(off[k]), g0), min(int(off[k + 1]), g1)  # layout range
            s0 = int(self.lo[k]) + (p0 - int(off[k]))  # its samples in x
            a, b = max(s0, 0), min(s0 + (p1 - p0), n)
            if b > a:
                buf[p0 - g0 + (a - s0) : p0 - g0 + (b - s0)] = x[a:b]
            k += 1
        return buf


def _window_spans(windows, n, lo, hi, m):
    """Per window: the lags ``[a, b)`` whose correlation the search and noise need."""
    out = []
    for s0, s1 in windows:
        s0, s1 = max(0, int(s0)), min(n, int(s1))
        if s1 - s0 < 3:
            out.append((s0, s0))
            continue
        l_, h_ = (0, s1 - s0) if lo is None else (lo, hi)
        a = max(s0, s0 + int(l_) - m - _SPAN_PAD)
        b = min(s1, s0 + int(h_) + m + _SPAN_PAD)
        if b - a < NOISE_MIN_SPAN:  # widen within the window for a robust noise level
            extra = NOISE_MIN_SPAN - (b - a)
            a2 = max(s0, a - extra // 2)
            b = min(s1, b + extra - (a - a2))
            a = max(s0, min(a2, b - NOISE_MIN_SPAN))
        out.append((a, max(a, b)))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


@kernel_by_length
def detect_matched(
    x: np.ndarray,
    *,
    fs: float,
    template: np.ndarray,
    windows: np.ndarray | None = None,
    search: tuple[int, int] | None = None,
    k_noise: float = DEFAULT_K_NOISE,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    k_detect: float = DEFAULT_K_DETECT,
    block: int = DEFAULT_BLOCK,
    model=None,
    q0: float = 4.0,
    groups: Sequence[int] | None = None,
    pool: bool = True,
) -> Arrivals:
    """First-path arrivals of ``template`` in one channel, one per window at most.

    Parameters
    ----------
    x : ndarray
        One channel of the recording.
    fs : float
        Sample rate in Hz.
    template : ndarray
        Matched-filter template (:func:`coded_template`); lag 0 = its first sample.
    windows : ndarray of int, shape (n, 2), optional
        ``[start, stop)`` sample ranges to search separately (e.g. one per activation);
        default one window over the whole channel.
    search : (int, int), optional
        Lags ``[lo, hi)`` relative to each window's start that may hold the arrival
        (e.g. from the ranges the system can measure); default the whole window.
    k_noise, rel_threshold, k_detect : float
        Detection and first-path thresholds (see :func:`first_path`).
    block : int
        Overlap-save FFT size.
    model : rangekit.detect.pathfit.ResonatorModel, optional
        Time each arrival by fitting the drive through resonators of unknown Q and f0,
        with overlapping paths (:func:`rangekit.detect.pathfit.fit_arrival`), instead of
        the template's peak: the template then only finds the arrivals. Default None: the
        template's envelope peak (its transducers assumed known).
    q0 : float
        With ``model``: the Q the first fit of each group starts its scan from (later
        arrivals of the group start from the group's estimate).
    groups : sequence of int, optional
        With ``model``: a label per window; windows with equal labels went through the
        same transducers (e.g. the transmitter id of each activation window), so their
        ``(Q, f0)`` estimates are pooled (:func:`rangekit.detect.pathfit.pool_fits`).
        Default: all windows one group.
    pool : bool
        With ``model``: pool the groups' estimates (default True). False: every arrival
        is fitted on its own (Q and f0 free), so its result does not depend on the other
        windows (slower).

    Returns
    -------
    Arrivals
        ``onset`` is the absolute sub-sample lag of each window's first path from sample 0
        (windows with none are dropped; ``window`` holds the window index of each),
        ``sigma`` its 1-sigma in samples, ``snr_db`` the matched-filter output SNR
        ``10 log10(2 E / N0)``, ``confidence`` the first path's height over the strongest
        peak's, ``burst_onsets[:, 0]`` the onset again (one burst per arrival), ``flags``
        ``low_snr`` below ``LOW_SNR_FACTOR * k_detect`` noise scales and, with ``model``,
        ``poor_match`` (the fitted model leaves more than ``POOR_MATCH_MISFIT`` of the
        energy unexplained) and ``ambiguous_first_path`` (a stronger path within the
        model's resolution after the first one).
    """
    fs = V.sample_rate(fs)
    x = _check_x("x", x)  # float32 recordings stay float32 (fits read float64 segments)
    mf = matched_filter(template, block=block)
    beta = rms_bandwidth_hz(mf.template, fs=fs)
    if windows is None:
        windows = np.array([[0, len(x)]])
    windows = np.asarray(windows, dtype=np.int64).reshape(-1, 2)
    lo, hi = (None, None) if search is None else (int(search[0]), int(search[1]))
    m = len(mf.self_response) // 2
    spans = _window_spans(windows, len(x), lo, hi, m)
    corr = _window_correlations(x, mf.template, spans, block=block)
    noise_scale = 1.0 / math.sqrt(mf.energy)  # envelope noise scale -> per-sample sigma
    labels = np.zeros(len(windows), dtype=np.int64) if groups is None else np.asarray(groups)
    if len(labels) != len(windows):
        raise InvalidParameterError(f"groups has {len(labels)} labels for {len(windows)} windows")
    rows: list[list] = []
    fits: list = []
    early: list[bool] = []
    warm: dict = {}
    low = LOW_SNR_FACTOR * k_detect
    for w, (s0, s1) in enumerate(windows):
        s0, s1 = max(0, int(s0)), min(len(x), int(s1))
        a, b = (int(v) for v in spans[w])
        if s1 - s0 < 3 or b - a < 3:
            continue
        cw, noise, env = corr[w]
        l_, h_ = (0, s1 - s0) if lo is None else (lo, hi)
        p = first_path(
            cw,
            lo=l_ - (a - s0),
            hi=h_ - (a - s0),
            noise=noise,
            k_noise=k_noise,
            rel_threshold=rel_threshold,
            k_detect=k_detect,
            self_response=mf.self_response,
            env=env,
        )
        if p is None or _silent_input(x, a + int(round(p.lag)), mf.n_taps):
            continue
        fit = None
        if model is not None:
            sigma_fit = _sample_noise(x[s0 : max(s0, a + int(p.lag) - mf.n_taps)])
            if not 0.1 * noise * noise_scale <= sigma_fit <= 2.0 * noise * noise_scale:
                sigma_fit = noise * noise_scale
            fit = _fit_window(
                x, a + p.lag, model, sigma_fit, q0, warm if pool else {},
                int(labels[w]),
                k_noise, rel_threshold, s0 + l_, s0 + h_, low,
            )  # fmt: skip
        top = float(env[int(round(p.strongest_lag))])
        sigma = 1.0 / (2.0 * math.pi * beta * p.snr) * fs if p.snr > 0 else math.inf
        rows.append([a + p.lag, sigma, p.snr, p.height / top, w])
        fits.append(fit)
        first = (fit.onset if fit is not None else a + p.lag) - a
        early.append(
            _earlier_candidate(
                cw, lo=l_ - (a - s0), first=first, noise=noise, reach=mf.n_taps,
                k=0.5 * (k_detect + k_noise), rel=rel_threshold, env=env,
            )
        )  # fmt: skip
    if model is not None and pool and rows:
        from rangekit.detect.pathfit import pool_fits

        wl = np.array([r[4] for r in rows])
        for g in np.unique(labels[wl]):
            idx = np.flatnonzero(labels[wl] == g)
            pooled, _ = pool_fits([fits[i] for i in idx])
            for i, f in zip(idx.tolist(), pooled, strict=True):
                fits[i] = f
    flags = np.zeros(len(rows), dtype=np.int64)
    for i, f in enumerate(fits):
        if f is not None:
            rows[i][0] = f.onset
            rows[i][1] = _fit_sigma(f, fs)
            rows[i][2] = f.snr
            rows[i][3] = float(f.amplitudes[f.first] / f.amplitudes.max())
            flags[i] |= _fit_flags(f)
        elif model is not None:
            flags[i] |= flag_bit("poor_match")  # nothing the model could fit
        if rows[i][2] < low:
            flags[i] |= flag_bit("low_snr")
        if early[i]:
            flags[i] |= flag_bit("ambiguous_first_path")
    if not rows:
        e = Arrivals.empty(fs=fs, n_bursts=1, detector="matched")
        return Arrivals(
            e.onset,
            fs,
            e.sigma,
            e.snr_db,
            e.confidence,
            e.burst_onsets,
            "matched",
            np.zeros(0, dtype=int),
        )
    arr = np.array(rows, dtype=np.float64)
    onset = arr[:, 0]
    snr_db = 20.0 * np.log10(np.maximum(arr[:, 2], 1e-300))
    conf = np.minimum(arr[:, 3], 1.0)
    return Arrivals(
        onset,
        fs,
        arr[:, 1],
        snr_db,
        conf,
        onset[:, None].copy(),
        "matched",
        arr[:, 4].astype(int),
        flags,
    )


#: Free fits (Q and f0 estimated) of a group before later arrivals hold the group's
#: estimate during their fits (they still inform the pooled estimate).
N_FREE_FITS = 3


def _fit_window(x, lag, model, sigma, q0, warm, g, k_noise, rel_threshold, lo, hi, low):
    """The transducer fit of one window's arrival; updates the group's running estimate.

    ``warm[g]`` holds ``[sum info, sum info theta, n, theta_held]``: the group's arrivals
    so far (above the low-SNR level). The first ``N_FREE_FITS`` are fitted with Q and f0
    free; later ones hold ``theta_held``, refreshed when the count doubles, unless the
    arrival's own estimate disagrees with it by more than 4 sigma (then refitted free).
    """
    from rangekit.detect.pathfit import fit_arrival

    acc = warm.get(g)
    kw = {"k_noise": k_noise, "rel_threshold": rel_threshold, "lo": lo, "hi": hi}
    fit = None
    if acc is not None and acc[2] >= N_FREE_FITS:
        th = acc[3]
        fit = fit_arrival(x, lag, model=model, sigma=sigma, q0=math.exp(th[0]), f0=th[1],
                          hold=True, **kw)  # fmt: skip
        if fit is not None:
            dev = fit.theta_hat - th
            if float(dev @ fit.info @ dev) > 16.0:
                fit = None
    if fit is None:
        fit = fit_arrival(x, lag, model=model, sigma=sigma, q0=q0, **kw)
    if fit is not None and fit.snr >= low and np.linalg.det(fit.info) > 0:
        if acc is None:
            acc = warm[g] = [np.zeros((2, 2)), np.zeros(2), 0, None]
        acc[0] = acc[0] + fit.info
        acc[1] = acc[1] + fit.info @ fit.theta_hat
        acc[2] += 1
        n = acc[2]
        if n >= N_FREE_FITS and (acc[3] is None or n & (n - 1) == 0):
            try:
                acc[3] = np.linalg.solve(acc[0], acc[1])
            except np.linalg.LinAlgError:
                acc[3] = fit.theta_hat
    return fit


def _fit_sigma(f, fs: float) -> float:
    """A fit's onset sigma (samples) with the model-error term of its misfit.

    A model that leaves a fraction ``eps`` of the arrival's energy unexplained can move
    the onset by about ``sqrt(eps)`` of the waveform's duration scale (the shape term of
    ``rangekit.detect.template``, ``sqrt(eps) / (2 pi beta)``), taken here as the fitted
    model's resolution (the half width of its autocorrelation envelope at one half). Only
    the misfit beyond 3 standard deviations of the noise's chi-square counts: below that
    it is the noise's own scatter, which the Cramér-Rao term already holds.
    """
    z = f.misfit_z
    eps = max(f.misfit, 0.0) * (1.0 - MISFIT_Z_FREE / z) if z > MISFIT_Z_FREE else 0.0
    return math.sqrt(f.sigma**2 + eps * f.resolution**2)


def _silent_input(x: np.ndarray, lag: int, n_taps: int) -> bool:
    """Whether the recording is exactly zero over the samples the matched filter read at
    ``lag`` and one template length before (digital silence): a peak there is the FFT's
    rounding of louder samples elsewhere in its block, measured against a window noise
    level that is rounding too (windows of zeros before an activation gave "arrivals" at
    17-22 dB SNR, flagged ``low_snr`` and ``poor_match``), not sound."""
    a, b = max(0, lag - n_taps), min(len(x), lag + n_taps)
    return b <= a or not np.any(x[a:b])


def _sample_noise(x: np.ndarray) -> float:
    """Standard deviation per sample of the noise in ``x`` (NaN if too short).

    The transducer fit compares its residual with this, sample by sample, so it must be
    the raw samples' noise, and precise: the matched-filter envelope's median has too few
    independent samples (its correlation length is the template's) for a chi-square test
    over a few hundred samples. Taken before the arrival (in a room, later reflections
    fill the rest of the window); robust to a few outliers (samples beyond 5 MAD-based
    deviations are left out).
    """
    if len(x) < NOISE_MIN_PRE:
        return math.nan
    x = np.asarray(x, dtype=np.float64)
    d = x - _median(x)
    ad = np.abs(d)
    s = 1.4826 * _median(ad)
    if not s > 0:
        return math.nan
    return float(np.std(d[ad < 5.0 * s]))


def _median(v: np.ndarray) -> float:
    """``np.median`` of a finite 1-D array, by one partition (the same value)."""
    n = len(v)
    k = n // 2
    p = np.partition(v, k)
    if n % 2:
        return float(p[k])
    # The (k-1)-th smallest is the largest of those partitioned below the k-th (one
    # partition: partitioning at (k - 1, k) selects twice, 6x slower at n = 8700).
    return float((p[:k].max() + p[k]) / 2.0)


def _earlier_candidate(c, *, lo, first, noise, reach, k, rel, env=None) -> bool:
    """Whether the envelope holds a peak the first-path rule passed over, well before it.

    A local maximum earlier than the first path by more than the template's reach (so
    not its own side lobe), above ``k`` noise scales (between the detection and the
    first-path thresholds: a direct path weaker than a reflection at low SNR) and above
    ``rel`` times the first path's height. ``env``: ``np.abs(c)`` if the caller has it.
    """
    env = np.abs(c) if env is None else env
    i1 = int(math.floor(first)) - int(reach)
    i0 = max(1, int(lo))
    if i1 - i0 < 3 or not 0 <= int(round(first)) < len(env):
        return False
    seg = env[i0:i1]
    h = float(env[int(round(first))])
    thr = max(k * noise, rel * h)
    cand = (seg > thr) & (seg >= env[i0 - 1 : i1 - 1]) & (seg >= env[i0 + 1 : i1 + 1])
    return bool(np.any(cand))


def _fit_flags(f) -> int:
    bits = 0
    if f.misfit > POOR_MATCH_MISFIT and f.misfit_z > POOR_MATCH_Z:
        bits |= flag_bit("poor_match")
    t0 = f.onsets[f.first]
    a0 = f.amplitudes[f.first]
    later = (f.onsets > t0) & (f.onsets - t0 <= AMBIGUOUS_RESOLUTIONS * f.resolution)
    if np.any(later & (f.amplitudes > a0)):
        bits |= flag_bit("ambiguous_first_path")
    return bits
