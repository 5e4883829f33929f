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

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import CodedBurst, burst_waveform, check_burst_fits
from rangekit.signals.spectrum import rms_bandwidth_hz
from rangekit.signals.transducer import Transducer, apply_chain
from rangekit.types import Arrivals

__all__ = [
    "DEFAULT_BLOCK",
    "MatchedFilter",
    "PathPeak",
    "coded_template",
    "crb_delay_s",
    "detect_matched",
    "first_path",
    "interp_peak",
    "noise_level",
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
    n_tail = int(math.ceil(4.0 * (tail_db / 20.0) * math.log(10.0) * q / (math.pi * f0) * fs))
    y = apply_chain(np.concatenate([drive, np.zeros(n_tail)]), (tx, rx), fs=fs)
    e = np.cumsum(y[::-1] ** 2)[::-1]
    keep = int(np.searchsorted(-e, -e[0] * 10.0 ** (-tail_db / 10.0)))
    return np.ascontiguousarray(y[: max(keep, len(drive))])


def _analytic_fir(h: np.ndarray) -> tuple[np.ndarray, int]:
    """The analytic version of real FIR ``h`` as a finite complex FIR.

    Returns ``(g, pre)`` with ``g[k + pre] = h_a[k]`` for ``k`` in ``[-pre, len(g) - pre)``.
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
    lo = int(np.searchsorted(c, 0.5 * _ANALYTIC_TAIL * total))
    hi = int(np.searchsorted(c, (1.0 - 0.5 * _ANALYTIC_TAIL) * total)) + 1
    lo = min(lo, n // 2)
    hi = max(hi, n // 2 + n_h)
    return np.ascontiguousarray(ha[lo:hi]), n // 2 - lo


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
    """

    def __init__(self, template: np.ndarray, *, block: int = DEFAULT_BLOCK) -> None:
        h = V.signal_1d("template", template)
        if len(h) < 2 or not np.any(h):
            raise InvalidParameterError("template must have at least 2 samples, not all zero")
        self.template = h
        self.energy = float(h @ h)
        g, pre = _analytic_fir(h)
        self.pre = pre
        self.n_taps = len(g)
        n = V.positive_int("block", block, minimum=16)
        while n < 4 * self.n_taps:
            n *= 2
        self.n_fft = n
        self.step = n - self.n_taps + 1
        from scipy import fft as sfft

        self._fft = sfft
        # Correlation with g = convolution with conj(g) reversed; the FFT of the taps
        # placed at [0, n_taps) correlates x_seg[j + k] with g[k].
        self._gr = np.conj(sfft.rfft(g.real, n))
        self._gi = -np.conj(sfft.rfft(g.imag, n))  # conj(g) has imaginary part -g.imag
        self._self_response: np.ndarray | None = None

    @property
    def self_response(self) -> np.ndarray:
        """The filter's output for its own template, centred: index ``len // 2`` is lag 0."""
        if self._self_response is None:
            z = np.zeros(self.n_taps + len(self.template))
            r = self.correlate(np.concatenate([z, self.template, z]))
            k = len(z)
            self._self_response = r[k - len(z) : k + len(z) + 1].copy()
        return self._self_response

    def _segments(self, xp: np.ndarray, n_out: int) -> np.ndarray:
        """Correlation outputs ``[0, n_out)`` of the padded input ``xp`` (x shifted by pre).

        The FFT blocks are strided windows of ``xp`` (no gathered copies) in batches of
        about 2^18 samples, small enough that their temporaries are reused rather than
        freshly mapped and zeroed by the OS (see ``docs/performance.md``).
        """
        from numpy.lib.stride_tricks import sliding_window_view

        sf, n, step = self._fft, self.n_fft, self.step
        out = np.empty(n_out, dtype=np.complex128)
        n_blocks = -(-n_out // step)
        need = (n_blocks - 1) * step + n
        if len(xp) < need:
            xp = np.concatenate([xp, np.zeros(need - len(xp))])
        win = sliding_window_view(xp, n)[::step]
        per = max(1, (1 << 18) // n)  # blocks per batched FFT call
        for b0 in range(0, n_blocks, per):
            b1 = min(n_blocks, b0 + per)
            X = sf.rfft(win[b0:b1], axis=1)
            s0 = b0 * step
            m = min(n_out - s0, (b1 - b0) * step)
            o = out[s0 : s0 + m]
            o.real = sf.irfft(X * self._gr, n, axis=1)[:, :step].reshape(-1)[:m]
            o.imag = sf.irfft(X * self._gi, n, axis=1)[:, :step].reshape(-1)[:m]
        return out

    def correlate(self, x: np.ndarray) -> np.ndarray:
        """Analytic correlation of the whole of ``x`` (complex, same length as ``x``)."""
        x = V.signal_1d("x", x)
        xp = np.concatenate([np.zeros(self.pre), x, np.zeros(self.n_taps)])
        return self._segments(xp, len(x))

    def stream(self, chunks: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
        """Correlate a signal given as consecutive chunks; yields output chunks in order.

        The outputs concatenated equal :meth:`correlate` of the concatenated input; memory
        is bounded by the chunk size plus one FFT block. Each output chunk lags its input
        by the template length (the correlation needs that much look-ahead).
        """
        buf = np.zeros(self.pre)
        done = 0  # outputs emitted so far
        seen = 0  # input samples seen so far
        look = self.n_taps - self.pre
        for chunk in chunks:
            c = V.signal_1d("chunk", chunk)
            buf = np.concatenate([buf, c])
            seen += len(c)
            ready = seen - look - done
            if ready > 0:
                yield self._segments(buf, ready)
                done += ready
                buf = buf[ready:]
        tail = seen - done
        if tail > 0:
            buf = np.concatenate([buf, np.zeros(self.n_taps)])
            yield self._segments(buf, tail)


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

    Returns
    -------
    PathPeak or None
        None when nothing in the search range clears the threshold.
    """
    env = np.abs(c)
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

    Returns
    -------
    Arrivals
        ``onset`` is the absolute sub-sample lag of each window's first path from sample 0
        (windows with none are dropped; ``window`` holds the window index of each),
        ``sigma`` its 1-sigma in samples, ``snr_db`` the matched-filter output SNR
        ``10 log10(2 E / N0)``, ``confidence`` the first path's height over the strongest
        peak's, ``burst_onsets[:, 0]`` the onset again (one burst per arrival).
    """
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    mf = MatchedFilter(template, block=block)
    c = mf.correlate(x)
    env = np.abs(c)
    beta = rms_bandwidth_hz(mf.template, fs=fs)
    if windows is None:
        windows = np.array([[0, len(x)]])
    windows = np.asarray(windows, dtype=np.int64).reshape(-1, 2)
    rows = []
    for w, (s0, s1) in enumerate(windows):
        s0, s1 = max(0, int(s0)), min(len(x), int(s1))
        if s1 - s0 < 3:
            continue
        seg = env[s0:s1]
        lo, hi = (0, s1 - s0) if search is None else search
        p = first_path(
            c[s0:s1],
            lo=lo,
            hi=hi,
            noise=noise_level(seg),
            k_noise=k_noise,
            rel_threshold=rel_threshold,
            k_detect=k_detect,
            self_response=mf.self_response,
        )
        if p is None:
            continue
        top = float(seg[int(round(p.strongest_lag))])
        sigma = 1.0 / (2.0 * math.pi * beta * p.snr) * fs if p.snr > 0 else math.inf
        rows.append((s0 + p.lag, sigma, 20.0 * math.log10(max(p.snr, 1e-300)), p.height / top, w))
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
    a = np.array(rows, dtype=np.float64)
    onset = a[:, 0]
    conf = np.minimum(a[:, 3], 1.0)
    return Arrivals(
        onset, fs, a[:, 1], a[:, 2], conf, onset[:, None].copy(), "matched", a[:, 4].astype(int)
    )
