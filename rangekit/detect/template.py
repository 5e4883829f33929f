"""Arrivals of any probe signal (a sweep, a chirp, a lab's own file) by matched filtering.

The beep detectors look for rangekit's burst train; this one finds every arrival of a
given :class:`~rangekit.signals.probe.Probe` in a channel, on recordings from any phone,
room or transducer (theory and measurements: ``docs/theory/probes.md``):

1. **Template**: the probe at the recording's rate (:meth:`Probe.at_rate`: polyphase
   resampling when the rates differ, an error when its band does not fit).
2. **Conditioning**: clipped samples (:func:`~rangekit.detect.condition.clip_mask`) are
   zeroed, so they stay out of the
   correlation; the noise spectrum is estimated from the recording
   (:func:`~rangekit.detect.matched.welch_spectra`, a low percentile over segments) and
   the matched filter is weighted by it (``weighting``; default ``"ml"``, the
   maximum-likelihood ``S*(f) / N(f)`` of Knapp & Carter 1976's family, chosen by
   measurement) and band-limited to the probe's band
   (:func:`~rangekit.detect.condition.bandpass_taps`): one zero-phase FIR applied to
   ``x`` with its group delay removed (:func:`~rangekit.detect.condition.bandlimit`).
   It is real and even in frequency, so it moves no arrival, and the first-path rule
   compares peaks with the *weighted* self response.
3. **Analytic matched filter** (:class:`rangekit.detect.matched.MatchedFilter`,
   overlap-save, cached per probe and rate): the envelope ``|c|``.
4. **Arrivals** (:func:`_select`): local maxima of the envelope above ``k_rec =
   max(k_detect, sqrt(2 ln(n / FALSE_ALARM)))`` times the noise's Rayleigh scale,
   strongest first; a peak within ``min_separation_s`` of a stronger accepted one
   belongs to it; a peak that does not clear ``k_rec`` times the *local* floor before
   its cluster, or lies under an earlier arrival's extrapolated tail, is that arrival's
   reverberation, ringing or echo, not a new arrival. With ``expected`` exactly that
   many are kept when that many are detectable (tail peaks only to fill, flagged
   ``reverb_limited``).
5. **First path** (:func:`rangekit.detect.matched.first_path`): within each arrival's
   cluster (peaks chained back from the strongest with gaps of at most ``lookback_s``),
   the earliest peak above ``max(k_noise * floor, rel_threshold * strongest)`` that is
   not a side lobe of the strongest path nor of up to :data:`N_CLEAN_PATHS` stronger
   later paths.
6. **Sub-sample lag** by a Gaussian fit of the envelope (:func:`interp_peak`; wide
   probes phase-coherently, :mod:`rangekit.detect._coherent`); 1-sigma
   ``sqrt(crb^2 + interp^2 + shape^2 + def^2 + td^2 + leak^2)``: the Cramér–Rao bound,
   the interpolation error of the weighted peak shape, the shift an unmodelled component
   of the peak (unresolved multipath, transducer mismatch) can cause (what neither the
   path nor the CLEANed other paths explain, :func:`_unexplained`), the two timings'
   disagreement beyond their own errors, the pull of later paths' range side lobes
   (:func:`_leakage`; removed from the onset where it is small, and kept in sigma), and
   the transducers' unknown delay of what the timing reads (:func:`transducer_sigma`: the
   group delay in the probe's band for the envelope, the pulse peak's delay behind the
   propagation onset for the phase-coherent timing; also in ``Arrivals.sigma_transducer``,
   which two-way ranging leaves out because it cancels there).
7. **Flags** (:data:`rangekit.types.ARRIVAL_FLAGS`): ``clipped``, ``low_snr``,
   ``ambiguous_first_path`` (also where the recording starts at or after the peak of a
   path above the first-path threshold: it cannot be searched), ``poor_match`` (sub-band
   coverage, :func:`_coverage`),
   ``reverb_limited``, ``dc_or_lowband``.

The onset of an arrival is the float sample index at which the probe's sample 0 arrived.

Examples
--------
>>> from rangekit.signals.probe import linear_sweep
>>> p = linear_sweep(17000.0, 20000.0, 0.1)
>>> x = np.zeros(20000)
>>> x[3000 : 3000 + 4410] += p.samples
>>> x[12000 : 12000 + 4410] += 0.01 * p.samples
>>> a = detect_template(x, fs=44100.0, probe=p)
>>> a.onset.round(3).tolist()
[3000.0, 12000.0]
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from rangekit import _validate as V
from rangekit.detect._coherent import (
    COHERENT_SIDE,
    SINC_HALF,
    _sinc_at,
    coherent_interp_rms,
    coherent_lag,
    coherent_weight,
    real_side_ratio,
)
from rangekit.detect.condition import bandlimit, bandpass_taps, clip_mask, dilate
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    DEFAULT_K_DETECT,
    DEFAULT_K_NOISE,
    DEFAULT_REL_THRESHOLD,
    NOISE_FLOOR_REL,
    WEIGHTINGS,
    MatchedFilter,
    Spectra,
    first_path,
    interp_peak,
    noise_level,
    weighting_response,
    welch_spectra,
    zero_phase_taps,
)
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals.probe import Probe
from rangekit.types import Arrivals, flag_bit

__all__ = [
    "DEFAULT_LOOKBACK_S",
    "DEFAULT_TRANSDUCER_RIPPLE_DB",
    "DEFAULT_WEIGHTING",
    "FALSE_ALARM",
    "POOR_MATCH_COVERAGE",
    "detect_template",
    "noise_spectra",
    "transducer_sigma",
]

#: Default time before an arrival's strongest peak searched for an earlier direct path, s
#: (20 ms: a reflection up to 6.9 m longer than the direct path).
DEFAULT_LOOKBACK_S = 0.020
#: Probability that a recording of noise alone yields an arrival (sets the detection
#: threshold together with the recording's length; see :func:`detect_template`).
FALSE_ALARM = 1e-3
#: Default weighting of the matched filter (see ``docs/theory/probes.md`` for the
#: measurements that chose it).
DEFAULT_WEIGHTING = "ml"
#: Default separation with ``expected``: at least the probe's duration, else this (s) or
#: half of each emission's share of the recording, whichever is shorter.
EXPECTED_SEP_S = 0.1
#: Stronger later paths whose side lobes are removed before an earlier peak counts as
#: the first path (:func:`rangekit.detect.matched.first_path`, ``n_paths``).
N_CLEAN_PATHS = 3
#: A later peak is an earlier arrival's tail unless it exceeds that tail's extrapolated
#: maximum by this factor (6 dB; :func:`_decay`).
TAIL_MARGIN = 2.0
#: ``low_snr``: the first path's SNR is below this multiple of the detection threshold.
LOW_SNR_FACTOR = 2.0
#: ``ambiguous_first_path``: another path within the resolution at least this fraction
#: of the chosen path's height ...
AMBIGUOUS_REL = 0.5
#: ... or the choice was within this factor of the first-path threshold.
AMBIGUOUS_MARGIN = 1.5
#: Other paths (CLEAN steps) whose range side lobes' pull on the first path enters sigma
#: (:func:`_leakage`).
LEAK_PATHS = 8
#: ... and the first path is moved back by that pull when it is at most this fraction of
#: the main lobe's half width (where the first-order estimate holds).
LEAK_CORRECT_LOBE = 0.25
#: Share of a removed pull kept in sigma: what the first order leaves (measured 0.2-0.41
#: of the pull on two paths 1.5-5 ms apart at 0.5-2x).
LEAK_RESIDUAL = 0.5
#: Sub-bands of the probe's band tested by the template-match check (:func:`_coverage`).
N_SUBBANDS = 8
#: A sub-band is present when its correlation at the onset reaches this fraction of the
#: best sub-band's (per unit of expected share; -26 dB: the steep high-frequency roll-off of
#: real loudspeakers over a wide band passes, see docs/theory/probes.md).
SUBBAND_PRESENT = 0.05
#: A sub-band is tested when the right template would put it this many noise deviations
#: up ...
SUBBAND_POWER = 4.0
#: ... and present when it is this many up.
SUBBAND_Z = 2.5
#: ``poor_match``: the present sub-bands hold less than this share of the template's
#: (weighted) energy (chosen by measurement, ``docs/theory/probes.md``).
POOR_MATCH_COVERAGE = 0.5
#: Envelope samples at or under this fraction of the largest are digital silence, left
#: out of the recording's noise level (:func:`_not_silent`).
SILENCE_REL = 1e-12
#: ``reverb_limited``: the local floor before an arrival exceeds the recording's noise
#: floor by this factor.
REVERB_FACTOR = 2.0
#: ``dc_or_lowband``: noise PSD more than this factor above the band's median ...
LOWBAND_PSD_FACTOR = 10.0
#: ... holding more power than the noise in the probe's band.
LOWBAND_POWER_RATIO = 1.0
#: Energy the template's analytic FIR may leave out (its Hilbert tails; the ultrasonic
#: filter keeps 1e-9): -70 dB in amplitude, below any recording's noise, and a 1 s
#: 20 Hz-20 kHz sweep's filter shrinks from 810k to 227k taps.
ANALYTIC_TAIL = 1e-7
#: Magnitude ripple (dB, peak) of the loudspeaker-microphone chain assumed across a probe's
#: band for the transducer term of ``sigma`` (:func:`transducer_sigma`): +-6 dB, a small
#: loudspeaker's or phone's (dEchorate's measured chains: 2.7-10.5 dB over 8-12 kHz).
DEFAULT_TRANSDUCER_RIPPLE_DB = 6.0
#: Band-limiting starts at DC (low-pass only) for probes reaching below this, Hz: the
#: noise weighting handles their low band; a high-pass edge there would need thousands
#: of taps.
_MIN_HIGHPASS_HZ = 500.0


def noise_spectra(x: np.ndarray, *, fs: float, probe: Probe) -> Spectra:
    """The noise spectrum :func:`detect_template` weights ``probe``'s filter by, for ``x``.

    Give :func:`rangekit.detect.matched.common_spectra` of every device's spectrum to
    each device's :func:`detect_template` (``spectra=``) so that all of an exchange's
    recordings are weighted alike.
    """
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    return welch_spectra(x, fs=fs, nperseg=_base(probe, fs, DEFAULT_BLOCK).nperseg)


def transducer_sigma(beta: float, ripple_db: float = DEFAULT_TRANSDUCER_RIPPLE_DB) -> float:
    """1-sigma (in the unit of ``1 / beta``) of the transducers' unknown delay that a timing
    of a band reads as propagation.

    The loudspeaker-microphone chain ``H(f) = |H| exp(j (phi_0 - 2 pi f tau_0 + delta(f)))``
    delays the propagation onset by a fixed ``tau_0`` (the chain's latency, the same in
    every arrival through it); its phase departs from that pure delay by ``delta(f)``. A
    minimum-phase chain whose log-magnitude ripples by ``A`` nepers (``ripple_db / 8.686``)
    about a smooth trend has, by Bode's gain-phase relation (the phase is the Hilbert
    transform of ``ln |H|``), a phase ripple of the same amplitude, ``|delta| <= A`` rad.
    The envelope peak of the matched filter reads the weighted least-squares slope of the
    arrival's phase over the band, so it shifts by ``sum W (f - f_c) delta / (2 pi sum W
    (f - f_c)^2)``, at most (Cauchy-Schwarz) ``A / (2 pi beta)`` with ``beta`` the RMS
    bandwidth of the weighted spectrum about its centroid. The phase-coherent timing (the
    pulse's peak, the extremum of the real part) reads the slope through the origin,
    ``sum W f (phi_0 + delta) / (2 pi sum W f^2)``, at most ``A / (2 pi F)`` with ``F``
    the RMS frequency about 0: call this with ``beta=F`` for it. Unlike the shape term
    this part cannot be seen in the arrival: a phase slope is a delay. Derivation and
    measurements: ``docs/theory/probes.md`` (uncertainty).

    Examples
    --------
    An 8-12 kHz sweep (``beta`` about 1155 Hz) at 48 kHz, +-6 dB of ripple:

    >>> round(48000 * transducer_sigma(1155.0), 2)
    4.57
    """
    a = V.positive("ripple_db", ripple_db, allow_zero=True) / (20.0 / math.log(10.0))
    return a / (2.0 * math.pi * V.positive("beta", beta))


def detect_template(
    x: np.ndarray,
    *,
    fs: float,
    probe: Probe,
    expected: int | None = None,
    min_separation_s: float | None = None,
    lookback_s: float = DEFAULT_LOOKBACK_S,
    k_noise: float = DEFAULT_K_NOISE,
    rel_threshold: float = DEFAULT_REL_THRESHOLD,
    k_detect: float = DEFAULT_K_DETECT,
    weighting: str = DEFAULT_WEIGHTING,
    spectra: Spectra | None = None,
    block: int = DEFAULT_BLOCK,
    transducer_ripple_db: float = DEFAULT_TRANSDUCER_RIPPLE_DB,
    what: str = "the recording",
) -> Arrivals:
    """Every arrival of ``probe`` in one channel, first path each, in time order.

    Parameters
    ----------
    x : ndarray
        One channel of the recording.
    fs : float
        Its sample rate in Hz (the probe is resampled to it).
    probe : Probe
        The emitted signal.
    expected : int, optional
        Number of emissions in the channel (e.g. one per device of an exchange): exactly
        this many arrivals are returned when that many are detectable, the strongest
        that are not another arrival's tail.
    min_separation_s : float, optional
        Shortest time between the starts of two emissions, s (e.g. a firing period);
        peaks closer to a stronger arrival belong to it. Default: the probe's duration
        (plays do not overlap); with ``expected``, at least :data:`EXPECTED_SEP_S`
        (0.1 s) unless half of each emission's share of the recording is shorter.
    lookback_s : float
        How far before an arrival's strongest peak its direct path may lie (default
        20 ms); capped at half of ``min_separation_s``.
    k_noise, rel_threshold, k_detect : float
        Thresholds of :func:`rangekit.detect.matched.first_path`.
    weighting : {"ml", "prewhiten", "scot", "phat", "none"}
        Weighting of the matched filter by the recording's noise spectrum
        (:func:`rangekit.detect.matched.weighting_response`); ``"none"`` is the plain,
        unconditioned matched filter.
    spectra : Spectra, optional
        The noise spectrum to weight by (:func:`rangekit.detect.matched.welch_spectra`);
        default: this recording's. Giving every device of an exchange the same one keeps
        the weighting, and so the weighting's share of the transducers' dispersion in the
        onsets, the same for all of them (see ``docs/theory/probes.md``, limits).
    block : int
        Overlap-save FFT size.
    transducer_ripple_db : float
        Magnitude ripple (dB) of the loudspeaker and microphone assumed across the probe's
        band for the transducer term of ``sigma`` (:func:`transducer_sigma`); 0 for
        transducers known to be flat.
    what : str
        The recording, for error messages.

    Returns
    -------
    Arrivals
        ``detector="template"``; ``onset`` and ``sigma`` in samples (``sigma`` includes
        the model-error terms, never 0, and the transducer term ``sigma_transducer``,
        which two-way ranging leaves out); ``snr_db`` the first path's height over the
        local noise floor of the weighted output; ``confidence`` the first path's height
        over the arrival's strongest peak; ``burst_onsets[:, 0]`` repeats the onset;
        ``flags`` as in the module notes.

    Raises
    ------
    InvalidParameterError
        Bad parameters.
    IncompatibleInputError
        A sample rate the probe does not fit, or a recording shorter than the probe.

    Notes
    -----
    The 1-sigma in samples is ``sqrt(s_crb^2 + s_interp^2 + s_shape^2 + s_def^2 +
    s_td^2 + s_leak^2)`` with
    ``s_crb = fs / (2 pi beta_w snr)`` (``beta_w``: RMS bandwidth of the weighted
    spectrum ``|S|^2 W``; Kay 1993 §3.11), ``s_interp`` the RMS error of the Gaussian
    peak interpolation on the weighted self response over fractional delays, and
    ``s_shape = fs sqrt(eps) / (2 pi beta_w)`` where ``eps`` is the fraction of the
    envelope's energy within the main lobe around the first path that the self response
    does not explain, beyond the noise's share: by Cauchy–Schwarz an unmodelled
    component of relative energy ``eps`` shifts a correlation peak by at most
    ``sqrt(eps) / (2 pi beta)`` (derivation in ``docs/theory/probes.md``); the
    phase-coherent timing's share ``w`` (the real part's peak, of curvature ``(2 pi
    F_w)^2``, ``F_w`` the RMS frequency of ``|S|^2 W`` about 0) takes ``F_w`` for
    ``beta_w``, as its Cramér–Rao term does, and reads ``eps`` on the residual's odd part
    about the path only (:func:`_odd_eps`: the even part, ``e(tau - u) = (alpha / conj
    alpha) conj(e(tau + u))``, e.g. a magnitude-only change such as air absorption,
    leaves ``Re{conj(alpha) c}`` and ``|c|`` symmetric about ``tau`` and moves neither
    peak). For the envelope timing's share ``1 - w``,
    ``eps`` is read at the onset the pull was taken from, with the other paths of
    ``s_leak`` subtracted (:func:`_unexplained`): their side lobes in the main lobe *are*
    the pull, which ``s_leak`` holds, and were counted twice before (17-20 kHz in rooms:
    sigma 4x the errors). ``s_def`` the
    disagreement of the phase-coherent and envelope timings of a wide probe beyond the
    envelope's noise and both interpolation errors (``s_interp`` of each: the
    envelope's alone is 0.01 samples on a 20 Hz-20 kHz sweep); ``s_td =
    (1 - w) transducer_sigma(beta_w) + w transducer_sigma(F_w)`` the transducers' unknown
    delay (:func:`transducer_sigma`: the in-band group delay for the envelope, the pulse
    peak's delay behind the propagation onset for the phase-coherent timing), ``w`` the
    weight of the phase-coherent timing (0 for narrow probes); ``s_leak`` the first-order pull
    of the other paths' range side lobes on the envelope peak (:func:`_leakage`), which
    is taken off the onset when it is at most :data:`LEAK_CORRECT_LOBE` of the main
    lobe's half width (then :data:`LEAK_RESIDUAL` of it stays in sigma).
    """
    fs = V.sample_rate(fs)
    x = V.signal_1d("x", x)
    if not isinstance(probe, Probe):
        raise InvalidParameterError(f"probe must be a Probe, got {type(probe).__name__}")
    if expected is not None:
        expected = V.positive_int("expected", expected)
    if weighting not in WEIGHTINGS:
        raise InvalidParameterError(
            f"weighting={weighting!r} must be one of {', '.join(WEIGHTINGS)}"
        )
    if min_separation_s is not None:
        sep_s = min_separation_s
    elif expected is not None:
        # N emissions in the recording: echoes and reverberation up to EXPECTED_SEP_S
        # (at most half an emission's share of the recording) belong to their arrival.
        sep_s = max(probe.duration_s, min(EXPECTED_SEP_S, len(x) / fs / (2 * expected)))
    else:
        sep_s = probe.duration_s
    sep = max(1, int(round(V.positive("min_separation_s", sep_s) * fs)))
    look = int(round(V.positive("lookback_s", lookback_s, allow_zero=True) * fs))
    look = min(look, sep // 2)
    s_td_env = transducer_sigma(1.0, transducer_ripple_db)  # times 1 / beta below
    probe.check_fits(fs, what=what)
    if len(x) < 3:
        return _empty(fs)
    if probe.duration_s * fs > len(x):
        # No whole arrival fits, and the filter's cost would grow with the template rather
        # than the recording (a 20 s probe on 1.3 s took 8 s and 0.8 GB to find nothing).
        raise IncompatibleInputError(
            f"{what} ({len(x) / fs:.3g} s) is shorter than the probe "
            f"({probe.duration_s:.3g} s): no whole arrival of it fits"
        )
    base = _base(probe, fs, block)
    if weighting == "none":
        mask = np.zeros(0, dtype=bool)
        wf = _unweighted(probe, fs, block, look)
        lowband = False
        spectra = None
    else:
        mask = clip_mask(x)
        if mask.any():
            x = np.where(mask, 0.0, x)
        else:
            mask = np.zeros(0, dtype=bool)
        if spectra is None:
            spectra = welch_spectra(x, fs=fs, nperseg=base.nperseg)
        elif not isinstance(spectra, Spectra) or spectra.f_hz[-1] != 0.5 * fs:
            raise InvalidParameterError(f"spectra must be a Spectra of a recording at fs={fs:g} Hz")
        W = weighting_response(
            weighting, spectra, template_psd=base.template_psd, band_hz=base.band
        )
        wf = _weighted(probe, fs, block, W, look)
        lowband = _lowband(spectra, base.band)
    xc = wf.condition(x)
    c = wf.mf.correlate(xc)
    env = np.abs(c)
    noise = max(noise_level(_not_silent(env)), NOISE_FLOOR_REL * float(env.max()))
    # The noise envelope is Rayleigh: P(|c| > k noise) = exp(-k^2 / 2) per sample, so over
    # n samples a peak beyond sqrt(2 ln(n / FALSE_ALARM)) noise levels is a false alarm
    # with probability <= FALSE_ALARM (k_detect = 4.5 alone gives several per second).
    k_rec = max(k_detect, math.sqrt(2.0 * math.log(len(x) / FALSE_ALARM)))
    peaks = _local_maxima(env)
    peaks = peaks[env[peaks] > k_rec * noise]
    if len(peaks) == 0:
        return _empty(fs)
    sel = _select(env, peaks, noise=noise, k_rec=k_rec, k_noise=k_noise,
                  rel_threshold=rel_threshold, sep=sep, look=look, wf=wf,
                  expected=expected)  # fmt: skip
    clip_cum = None
    if len(mask):
        clip_cum = np.concatenate(([0], np.cumsum(dilate(mask, wf.reach), dtype=np.int64)))
    m = len(wf.self_resp) // 2
    rows = []
    for q, start, floor, tail in sel:
        # Before the first arrival the local floor is its own range side lobes (which the
        # first-path rule subtracts), not a floor: the recording's noise is.
        earlier = any(q2 < start for q2, _, _, _ in sel)
        if not (earlier or tail):
            floor = noise
        lo = min(start, q - 1)  # first_path needs 3 lags; lookback_s=0 is legal
        a0 = max(0, lo - m - 2)
        cs = c[a0 : q + m + 4]
        # A tail peak kept for ``expected`` may not clear k_detect over the local floor;
        # its floor for the search is capped so that it is still timed (and flagged).
        f_search = min(floor, float(env[q]) / (k_detect * 1.001))
        pk = first_path(
            cs,
            lo=lo - a0,
            hi=q + 2 - a0,
            noise=f_search,
            k_noise=k_noise,
            rel_threshold=rel_threshold,
            k_detect=k_detect,
            self_response=wf.self_resp,
            n_paths=N_CLEAN_PATHS,
        )
        if pk is None:  # cannot happen for a peak above k_detect * floor; kept for safety
            continue
        lag = a0 + pk.lag
        snr = pk.height / floor if floor > 0 else math.inf
        s_crb = 1.0 / (2.0 * math.pi * wf.beta * snr) if snr > 0 else math.inf
        s_interp = wf.interp_rms
        s_def = 0.0
        w = 0.0
        if wf.coherent_reach:
            # Wideband probe: the pulse's peak (real part), not its envelope's; the
            # envelope's disagreement beyond its noise is the arrival's phase distortion.
            coh = coherent_lag(c, lag, wf.coherent_reach)
            w = 0.0 if coh is None else coherent_weight(coh[1])
            if w > 0.0:
                d = coh[0] - lag
                # Beyond what the two timings' own errors explain: the envelope's noise
                # and the interpolation errors of both (properties of the filter).
                own = s_crb**2 + wf.interp_rms**2 + wf.coherent_rms**2
                s_def = math.sqrt(max(0.0, d**2 - own))
                s_coh = 1.0 / (2.0 * math.pi * wf.f_rms * snr) if snr > 0 else math.inf
                s_crb = w * s_coh + (1.0 - w) * s_crb
                s_interp = w * wf.coherent_rms + (1.0 - w) * s_interp
                lag += w * d
        j = int(round(lag))
        _, ambiguous_near = _shape(c, j, lag - j, wf, floor)
        # The chain's phase ripple moves the envelope peak by up to A / (2 pi beta_w) and
        # the pulse's peak (real part) by up to A / (2 pi F_w) (docs/theory/probes.md).
        s_td = ((1.0 - w) / wf.beta + w / wf.f_rms) * s_td_env
        # The pull is the envelope peak's: the phase-coherent share (w) is not moved.
        paths = _other_paths(c, j, lag - j, wf, k_noise * f_search)
        pull = (1.0 - w) * _leakage(c, j, lag - j, wf, paths)
        s_leak = pull
        if abs(s_leak) <= LEAK_CORRECT_LOBE * wf.half_lobe:
            lag -= s_leak  # first order holds: a fraction of the main lobe
            s_leak *= LEAK_RESIDUAL
        s_leak = abs(s_leak)
        # The shape term: what neither the path nor the other paths explain at the model's
        # peak. The envelope's share is read after the pull (at lag - pull, with the
        # CLEANed paths subtracted: their pull is s_leak's, not counted twice); the
        # phase-coherent share, which the pull does not move, on c itself.
        s_shape = 0.0
        if w > 0.0:
            # The real part's peak has curvature (2 pi F_w)^2: the bound with F_w, on the
            # residual's reflection-odd part (an even residual moves neither peak).
            eps_odd = _odd_eps(c, j, lag - j, wf, floor)
            s_shape += w * math.sqrt(eps_odd) / (2.0 * math.pi * wf.f_rms)
        if w < 1.0:
            lm = lag - (pull if abs(pull) > LEAK_CORRECT_LOBE * wf.half_lobe else 0.0)
            jm = int(round(lm))
            eps_m = _unexplained(c, jm, lm - jm, wf, floor, paths)
            s_shape += (1.0 - w) * math.sqrt(eps_m) / (2.0 * math.pi * wf.beta)
        sigma = math.sqrt(s_crb**2 + s_interp**2 + s_shape**2 + s_def**2 + s_td**2 + s_leak**2)
        bits = 0
        if clip_cum is not None:
            s0 = min(max(j, 0), len(x))
            s1 = min(max(j + len(base.template), 0), len(x))
            if clip_cum[s1] - clip_cum[s0] > 0:
                bits |= flag_bit("clipped")
        if snr < LOW_SNR_FACTOR * k_rec:
            bits |= flag_bit("low_snr")
        thr = max(k_noise * f_search, rel_threshold * float(env[q]))
        js = int(round(a0 + pk.strongest_lag))
        strongest = js != j
        if ambiguous_near or (strongest and pk.height < AMBIGUOUS_MARGIN * thr):
            bits |= flag_bit("ambiguous_first_path")
        elif _near_miss(c, env, lo, [(j, lag - j), (js, a0 + pk.strongest_lag - js)], wf, thr):
            bits |= flag_bit("ambiguous_first_path")
        if a0 == 0 and env[0] > thr and env[0] >= env[1]:
            # The recording starts at or after the peak of a path above the first-path
            # threshold: that path (at its first sample, with no neighbour before it: not
            # a local maximum) or one before it cannot be searched, and the lobe found may
            # be a later one (a probe starting at sample 0 was timed 18.9 samples late at
            # sigma 8.6 unflagged). A path peaking after sample 0 is searched as any other.
            bits |= flag_bit("ambiguous_first_path")
        if spectra is not None and _coverage(xc, j, base, wf, spectra) < POOR_MATCH_COVERAGE:
            bits |= flag_bit("poor_match")
        if tail or floor > REVERB_FACTOR * noise:
            bits |= flag_bit("reverb_limited")
        if lowband:
            bits |= flag_bit("dc_or_lowband")
        conf = min(pk.height / float(env[q]), 1.0)
        rows.append((lag, sigma, 20.0 * math.log10(max(snr, 1e-300)), conf, s_td, bits))
    if not rows:
        return _empty(fs)
    rows.sort()
    a = np.array([r[:5] for r in rows], dtype=np.float64)
    onset = a[:, 0]
    flags = np.array([r[5] for r in rows], dtype=np.int64)
    return Arrivals(
        onset, fs, a[:, 1], a[:, 2], a[:, 3], onset[:, None].copy(), "template", None, flags,
        a[:, 4],
    )  # fmt: skip


def _select(
    env: np.ndarray,
    peaks: np.ndarray,
    *,
    noise: float,
    k_rec: float,
    k_noise: float,
    rel_threshold: float,
    sep: int,
    look: int,
    wf: _Filter,
    expected: int | None,
) -> list[tuple[int, int, float, bool]]:
    """The arrivals: ``(strongest peak, cluster start, local floor, is a tail peak)``.

    Strongest first; a peak within ``sep`` of an accepted one is part of it. Each
    candidate's **cluster** is the run of peaks above ``max(k_noise noise,
    rel_threshold height)`` that reaches back from it with gaps of at most ``look``
    (reflections and reverberation follow the direct sound without a break, at most
    ``sep / 2`` back). The candidate must clear ``k_rec`` times the local floor just
    before its cluster (:func:`_local_floor`: noise, or the reverberation or ringing of
    what came before); a cluster reaching back to an accepted arrival, or a candidate
    below its floor, is a tail peak: it suppresses weaker peaks within ``look`` and is
    used only when ``expected`` asks for more arrivals than clear their floors.
    """
    order = peaks[np.argsort(-env[peaks], kind="stable")]
    all_pk = _local_maxima(env)
    taken: list[tuple[int, int, float, bool]] = []
    tails: list[tuple[int, int, float]] = []
    guard = max(look, 1)
    cap = max(sep // 2, 1)
    decays: list[tuple[int, tuple[float, float, float] | None]] = []
    for p in order.tolist():
        if any(abs(p - q) < sep for q, _, _, _ in taken):
            continue
        if any(abs(p - q) < guard for q, _, _ in tails):
            continue
        thr = max(k_noise * noise, rel_threshold * float(env[p]))
        start = _cluster_start(env, all_pk, p, thr, look, cap)
        floor = max(noise, _local_floor(env, start, look, wf.half_lobe))
        into = any(q < p and start <= q for q, _, _, _ in taken)
        into = into or any(
            q < p and env[p] < TAIL_MARGIN * _tail_level(decay, p) for q, decay in decays
        )
        if env[p] >= k_rec * floor and not into:
            taken.append((p, start, floor, False))
            decays.append((p, _decay(env, p, sep, look)))
            if expected is not None and len(taken) == expected:
                break
        else:
            tails.append((p, start, floor))
    if expected is not None and len(taken) < expected:
        for p, start, floor in tails:  # already strongest first
            if all(abs(p - q) >= sep for q, _, _, _ in taken):
                taken.append((p, start, floor, True))
                if len(taken) == expected:
                    break
    return taken


def _decay(env: np.ndarray, q: int, sep: int, look: int) -> tuple[float, float, float] | None:
    """Upper envelope of arrival ``q``'s tail: ``(a, b, t_end)`` with ``20 log10 level =
    a + b t`` (``t`` in samples) valid up to ``t_end``.

    A line fitted to the maxima of 8 blocks of the envelope over ``[q + look, q + sep)``
    (the stretch that belongs to ``q`` by the separation) and raised to pass over all of
    them: echoes and ringing
    inside that stretch lie under it, and it extrapolates the tail's decay beyond (a tail
    that does not decay is its maximum, over the stretch only). None when the stretch is
    too short.
    """
    lo = q + max(look, 1)
    hi = min(len(env), q + sep)
    if hi - lo < 64:
        return None
    edges = np.linspace(lo, hi, 9).astype(np.int64)
    t = 0.5 * (edges[:-1] + edges[1:])
    m = np.array([env[a:b].max() for a, b in itertools.pairwise(edges)])
    if np.any(m <= 0):
        return None
    y = 20.0 * np.log10(m)
    b, a = np.polyfit(t, y, 1)
    if b >= 0:  # echoes late in the stretch: flat at their maximum, up to its end only
        return float(y.max()), 0.0, float(hi)
    a += float(np.max(y - (a + b * t)))
    return float(a), float(b), math.inf


def _tail_level(decay: tuple[float, float, float] | None, p: int) -> float:
    """The envelope maximum an earlier arrival's tail reaches at ``p`` (0 without one)."""
    if decay is None or p > decay[2]:
        return 0.0
    a, b, _ = decay
    return 10.0 ** ((a + b * p) / 20.0)


def _cluster_start(
    env: np.ndarray, all_pk: np.ndarray, p: int, thr: float, look: int, cap: int
) -> int:
    """Earliest peak above ``thr`` reached from ``p`` backwards in steps of <= ``look``."""
    if look <= 0:
        return p
    a = int(np.searchsorted(all_pk, p - cap))
    b = int(np.searchsorted(all_pk, p))
    idx = all_pk[a:b]
    idx = idx[env[idx] >= thr]
    if len(idx) == 0:
        return p
    gaps = np.diff(np.concatenate([idx, [p]]))
    big = np.flatnonzero(gaps > look)
    if len(big) == 0:
        return int(idx[0])
    k = int(big[-1]) + 1
    return int(idx[k]) if k < len(idx) else p


def _not_silent(env: np.ndarray) -> np.ndarray:
    """The envelope without its digital silence: the samples over ``SILENCE_REL`` of its
    largest (exact zeros in the recording come out of the filter as rounding, ~1e-16);
    all of it when nothing is left. The noise level is their median: a recording that is
    more than half zeros (an app that starts silent) had a median of 0, a noise level at
    ``NOISE_FLOOR_REL`` of the peak, and arrivals in the silence at 15-70 dB SNR (the
    filter's -70 dB tails of the noise where it starts)."""
    live = env[env > SILENCE_REL * float(env.max())] if len(env) else env
    return live if len(live) else env


def _local_floor(env: np.ndarray, start: int, look: int, half_lobe: int) -> float:
    """Rayleigh scale of the envelope in the stretch just before a cluster starting at
    ``start``.

    The window ends a main lobe before ``start`` and is ``max(2 look, 32 half lobes,
    256)`` samples long (at most 4096): noise there, or the decaying tail of an earlier
    arrival. 0 when the window is (almost) empty.
    """
    end = start - 2 * half_lobe - 1
    n = min(4096, max(2 * look, 32 * half_lobe, 256))
    lo = max(0, end - n)
    if end - lo < 16:
        return 0.0
    return noise_level(env[lo:end])


def _near_miss(c: np.ndarray, env: np.ndarray, lo: int, paths, wf: _Filter, thr: float) -> bool:
    """An earlier peak in ``[lo, j)`` that nearly cleared the first-path threshold.

    ``paths``: ``(index, sub-sample offset)`` of the chosen and the strongest path; their
    own responses (side lobes) are subtracted first, as :func:`first_path` does.
    """
    j = min(p for p, _ in paths)
    a = max(lo, 1)
    b = j - wf.half_lobe
    if b - a < 1:
        return False
    seg = env[a:b]
    pk = np.flatnonzero((seg >= env[a - 1 : b - 1]) & (seg > env[a + 1 : b + 1]))
    pk = pk[seg[pk] >= thr / AMBIGUOUS_MARGIN]
    if len(pk) == 0:
        return False
    idx = a + pk
    res = c[idx].copy()
    m = len(wf.self_resp) // 2
    for p, d in {(int(p), float(d)) for p, d in paths}:
        R = _shifted(wf.self_resp, d)
        alpha = c[p] / R[m]
        k = idx - p + m
        ok = (k >= 0) & (k < len(R))
        res[ok] -= alpha * R[k[ok]]
    return bool(np.any(np.abs(res) >= thr / AMBIGUOUS_MARGIN))


def _lobe_fit(c: np.ndarray, j: int, d: float, wf: _Filter, half: int):
    """The window ``c[j - half : j + half + 1]`` beside the weighted self response shifted
    by ``d`` over the same lags, and the main lobe's (``j +- half_lobe``) energies and
    cross term: ``(R, seg, rr, ss, <r, s>)``, the least-squares ``alpha = <r, s> / rr``
    of :func:`_shape` and :func:`_odd_eps`. None when the window leaves ``c`` or the self
    response, or either lobe holds no energy."""
    K = wf.half_lobe
    m = len(wf.self_resp) // 2
    lo, hi = j - half, j + half + 1
    if lo < 0 or hi > len(c) or m < half + 1:
        return None
    R = _shifted(wf.self_resp, d)[m - half : m + half + 1]
    seg = c[lo:hi]
    core = slice(half - K, half + K + 1)
    r, s = R[core], seg[core]
    rr = float(np.vdot(r, r).real)
    ss = float(np.vdot(s, s).real)
    if rr <= 0 or ss <= 0:
        return None
    return R, seg, rr, ss, np.vdot(r, s)


def _shape(c: np.ndarray, j: int, d: float, wf: _Filter, floor: float) -> tuple[float, bool]:
    """Unexplained energy fraction of the main lobe at ``j + d``, and a close rival path.

    ``c`` over ``j +- half_lobe`` is fitted by ``alpha R(l - j - d)`` (``R``: the weighted
    self response shifted by ``d`` in the frequency domain, ``alpha`` complex least
    squares). Returns ``max(0, 1 - rho^2 - noise share)`` with ``rho`` the normalised
    correlation, and whether the residual ``c - alpha R`` holds another local maximum
    within ``+- 2 half_lobe`` that is at least :data:`AMBIGUOUS_REL` of the path's height
    (a path of comparable strength within the probe's resolution).
    """
    K = wf.half_lobe
    K2 = 2 * K
    fit = _lobe_fit(c, j, d, wf, K2)
    if fit is None:
        return 0.0, False
    R, seg, rr, ss, rs = fit
    alpha = rs / rr
    rho2 = abs(rs) ** 2 / (rr * ss)
    noise_share = (2 * K + 1) * 2.0 * floor**2 / ss
    eps = max(0.0, 1.0 - rho2 - noise_share)
    res = np.abs(seg - alpha * R)
    h = abs(alpha) * float(np.abs(R[K2]))
    pk = np.flatnonzero((res[1:-1] >= res[:-2]) & (res[1:-1] > res[2:])) + 1
    rival = bool(np.any(res[pk] >= AMBIGUOUS_REL * h)) if h > 0 else False
    return eps, rival


def _odd_eps(c: np.ndarray, j: int, d: float, wf: _Filter, floor: float) -> float:
    """Energy fraction of the main lobe at ``tau = j + d`` in the residual's odd part.

    The residual ``e = c - alpha R(l - tau)`` over ``tau +- half_lobe`` (``alpha``, ``R``
    as in :func:`_shape`) splits about ``tau`` into an even part, ``e(tau - u) = p
    conj(e(tau + u))`` with ``p = alpha / conj(alpha)`` (the symmetry of ``alpha R``
    itself: ``R(-u) = conj(R(u))``), and an odd part ``e_o(tau + u) = (e(tau + u) - p
    conj(e(tau - u))) / 2``; the reflected samples are read band-limited (Kaiser-windowed
    sinc, :func:`rangekit.detect._coherent._sinc_at`). Rotated by ``conj(alpha)``, an even
    part has an even real part and an odd imaginary part, so it adds an even function to
    ``Re{conj(alpha) c}`` and to ``|c|^2`` about ``tau``: it moves neither the real
    part's extremum nor the envelope's. Returns ``max(0, |e_o|^2 / |c|^2 -
    noise share / 2)`` over the main lobe (white noise splits evenly between the parts).
    0 when the window does not fit.
    """
    K = wf.half_lobe
    pad = SINC_HALF + 2  # the reflection's interpolation reaches this far beyond the lobe
    h = K + pad
    fit = _lobe_fit(c, j, d, wf, h)
    if fit is None:
        return 0.0
    R, seg, rr, ss, rs = fit
    core = slice(pad, pad + 2 * K + 1)
    alpha = rs / rr
    e = seg - alpha * R
    e_re, e_im = np.ascontiguousarray(e.real), np.ascontiguousarray(e.imag)
    p = alpha / np.conj(alpha) if abs(alpha) > 0 else 1.0
    # seg index h + d is tau; index i reflects to 2 (h + d) - i.
    refl = np.array(
        [
            complex(_sinc_at(e_re, 2 * h + 2 * d - i), _sinc_at(e_im, 2 * h + 2 * d - i))
            for i in range(pad, pad + 2 * K + 1)
        ]
    )
    e_odd = 0.5 * (e[core] - p * np.conj(refl))
    noise_share = (2 * K + 1) * 2.0 * floor**2 / ss
    return max(0.0, float(np.vdot(e_odd, e_odd).real) / ss - 0.5 * noise_share)


def _other_paths(
    c: np.ndarray, j: int, d: float, wf: _Filter, thr: float
) -> list[tuple[complex, int]]:
    """The other paths within the self response's reach of the path at ``j + d``:
    ``(amplitude, lag)`` of each, by a few CLEAN steps (Högbom 1974).

    The path is ``alpha R(l - j - d)`` (``alpha`` from ``c[j]``); from the residual the
    strongest peak above ``thr`` outside two main lobes is a path ``a_p R(l - p)``,
    subtracted, repeated up to :data:`LEAK_PATHS` times.
    """
    R = wf.self_resp
    m = len(R) // 2
    K2 = 2 * wf.half_lobe
    lo, hi = max(1, j - m + 1), min(len(c) - 1, j + m)
    if hi - lo < 2 * K2 + 3 or m < 2:
        return []
    Rs = _shifted(R, d)
    idx = np.arange(lo, hi)
    alpha = c[j] / Rs[m]
    if abs(alpha) == 0.0:
        return []
    res = c[lo:hi] - alpha * Rs[idx - j + m]
    far = np.abs(idx - j) > K2
    paths: list[tuple[complex, int]] = []
    for _ in range(LEAK_PATHS):
        e = np.where(far, np.abs(res), 0.0)
        k = int(np.argmax(e))
        if e[k] < thr:
            break
        p = int(idx[k])
        a = complex(res[k] / R[m])
        paths.append((a, p))
        ok = np.abs(idx - p) < m
        res[ok] -= a * R[idx[ok] - p + m]
    return paths


def _leakage(
    c: np.ndarray, j: int, d: float, wf: _Filter, paths: list[tuple[complex, int]]
) -> float:
    """Shift of the chosen path's envelope peak by other paths' range side lobes, samples.

    The path at ``j + d`` is ``alpha R(l - j - d)``; ``paths`` the others within the self
    response's reach (:func:`_other_paths`). To first order in their amplitudes the
    envelope peak moves by ``delta = -g'(j) / (|alpha|^2 |R_0| |R|''_0)``, ``g(l) =
    Re{conj(alpha R(l - j - d)) sum_p a_p R(l - p)}`` (from ``d|c|^2/dl = 0``), returned
    signed (the shape term covers what the paths leave unexplained, this their pull).
    Measured on two paths 1.5-5 ms apart at 0.5-2x: the estimate is 0.8-1.0x the actual
    pull.
    """
    R = wf.self_resp
    m = len(R) // 2
    if not paths or m < 2 or j < 1 or j + 1 >= len(c):
        return 0.0
    Rs = _shifted(R, d)
    alpha = c[j] / Rs[m]
    if abs(alpha) == 0.0:
        return 0.0
    g = []
    for t in (j - 1, j + 1):
        other = sum(a * R[t - p + m] for a, p in paths if abs(t - p) < m)
        g.append(float((np.conj(alpha * Rs[m + t - j]) * other).real))
    dg = 0.5 * (g[1] - g[0])
    env = np.abs(R[m - 1 : m + 2])
    curv = float(env[0] - 2.0 * env[1] + env[2])
    if curv >= 0.0:
        return 0.0
    return -dg / (abs(alpha) ** 2 * float(env[1]) * curv)


def _unexplained(
    c: np.ndarray, j: int, d: float, wf: _Filter, floor: float, paths: list[tuple[complex, int]]
) -> float:
    """:func:`_shape`'s unexplained fraction at ``j + d`` once ``paths`` are subtracted.

    The other paths (:func:`_other_paths`) are a model of the arrival too: their side
    lobes inside the main lobe and the shift of its peak that they cause are
    :func:`_leakage`'s, so they are taken out of ``c`` over the window :func:`_shape`
    reads before the fit (at the onset the pull has been removed from).
    """
    R = wf.self_resp
    m = len(R) // 2
    K2 = 2 * wf.half_lobe
    lo, hi = j - K2, j + K2 + 1
    if lo < 0 or hi > len(c):
        return 0.0
    seg = c[lo:hi].copy()
    idx = np.arange(lo, hi)
    for a, p in paths:
        ok = np.abs(idx - p) < m
        seg[ok] -= a * R[idx[ok] - p + m]
    return _shape(seg, K2, d, wf, floor)[0]


def _subband_edges(band: tuple[float, float], fs: float) -> np.ndarray:
    """Edges of :data:`N_SUBBANDS` equal sub-bands of the probe's band, Hz."""
    return np.linspace(band[0], min(band[1], 0.5 * fs), N_SUBBANDS + 1)


def _coverage(xc: np.ndarray, j: int, base: _Base, wf: _Filter, spectra) -> float:
    """Share of the template's energy whose sub-bands hold the arrival at onset ``j``.

    The correlation of the conditioned recording with the template at lag ``j`` is split
    into :data:`N_SUBBANDS` sub-bands of the probe's band (Parseval: ``r_b = sum over the
    band's bins of X S*``, ``X`` the spectrum of the template-long segment at ``j``).
    For the probe that was played every sub-band holds its share of the arrival (up to
    the transducers' ripple); a wrong template correlates with a recording only where
    the played signal shares its time-frequency path: in a part of the band (a beep's
    skirt, another sweep's overlap) or, for another chirp rate, a part at each lag.

    Each sub-band's noise ``sd_b`` follows from the recording's noise PSD through the
    conditioning FIR (``Var r_b = sum N |H|^2 |S|^2 fs n / 2``). A sub-band is *tested*
    when the arrival, were it the template, would put it at least :data:`SUBBAND_POWER`
    noise deviations up (its share of the full-band correlation); it is *present* when
    ``|r_b|`` is :data:`SUBBAND_Z` deviations up and, per unit of share, at least
    :data:`SUBBAND_PRESENT` of the best. Returns the tested share that is present (1 when
    under a third of the share can be tested: too weak an arrival to judge, which
    ``low_snr`` then reports).
    """
    h = base.template
    n = len(h)
    if j < 0 or j + n > len(xc):
        return 1.0
    fs = 2.0 * base.band_fs
    X = np.fft.rfft(xc[j : j + n])
    S = _template_spectrum(base)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    H = _taps_response(wf, n)
    N = np.interp(f, spectra.f_hz, spectra.noise) * H**2
    edges = _subband_edges(base.band, fs)
    cross = X * np.conj(S)
    S2 = np.abs(S) ** 2
    r, sd, e = [], [], []
    for lo, hi in itertools.pairwise(edges):
        k = (f >= lo) & (f < hi)
        r.append(abs(cross[k].sum()))
        sd.append(math.sqrt(max(float((N[k] * S2[k]).sum()) * fs * n / 2.0, 1e-300)))
        e.append(float((S2[k] * H[k]).sum()))
    r, sd, e = np.array(r), np.array(sd), np.array(e)
    sh = wf.shares
    gain = abs(cross[(f >= edges[0]) & (f < edges[-1])].sum()) / max(float(e.sum()), 1e-300)
    tested = (sh >= 0.25 / N_SUBBANDS) & (gain * e >= SUBBAND_POWER * sd)
    if sh[tested].sum() < 1.0 / 3.0:
        return 1.0
    a = np.where(tested, r / np.maximum(sh, 1e-300), 0.0)
    present = tested & (r >= SUBBAND_Z * sd) & (a >= SUBBAND_PRESENT * float(a.max()))
    return float(sh[present].sum() / sh[tested].sum())


def _taps_response(wf: _Filter, n: int) -> np.ndarray:
    """Real response of the conditioning FIR on ``rfftfreq(n)`` (1 without one)."""
    if wf.taps is None:
        return np.ones(n // 2 + 1)
    hw = wf.reach
    m = n
    while m < len(wf.taps):
        m *= 2
    t = np.zeros(m)
    t[: len(wf.taps)] = wf.taps
    H = np.fft.rfft(np.roll(t, -hw)).real
    if m != n:
        H = np.interp(np.fft.rfftfreq(n), np.fft.rfftfreq(m), H)
    return H


def _template_spectrum(base: _Base) -> np.ndarray:
    """The template's spectrum (cached on ``base``)."""
    if base.spectrum is None:
        object.__setattr__(base, "spectrum", np.fft.rfft(base.template))
    return base.spectrum


def _shifted(r: np.ndarray, d: float) -> np.ndarray:
    """``r`` (band-limited) delayed by ``d`` samples (exact in the frequency domain)."""
    n = len(r)
    f = np.fft.fftfreq(n)
    return np.fft.ifft(np.fft.fft(r) * np.exp(-2j * math.pi * f * d))


def _lowband(spectra, band: tuple[float, float]) -> bool:
    """Strong DC / low-band / out-of-band noise that the weighting removes.

    The noise power more than :data:`LOWBAND_PSD_FACTOR` above the band's median PSD
    (wherever it lies, DC included) exceeds :data:`LOWBAND_POWER_RATIO` times the noise
    power in the probe's band.
    """
    f, N = spectra.f_hz, spectra.noise
    inb = (f >= band[0]) & (f <= band[1])
    if not inb.any():
        return False
    med = float(np.median(N[inb]))
    if not med > 0:
        return False
    strong = np.maximum(N - LOWBAND_PSD_FACTOR * med, 0.0)
    # DC's power itself (Welch's Hann window spreads it over bins 0 and 1).
    return float(strong.sum()) > LOWBAND_POWER_RATIO * float(N[inb].sum())


@dataclass(frozen=True, eq=False)
class _Base:
    """What a probe's detection at one rate shares across recordings."""

    mf: MatchedFilter  # the unweighted filter
    template: np.ndarray
    band: tuple[float, float]
    bp_taps: np.ndarray | None  # band-limiting FIR (None: not needed)
    nperseg: int
    template_psd: np.ndarray  # |S|^2 on the weights' grid
    band_fs: float  # Nyquist frequency of the rate, Hz
    spectrum: np.ndarray | None = None  # rfft of the template, filled on first use


@dataclass(frozen=True, eq=False)
class _Filter:
    """A (weighted) filter with what the arrival rules need of it."""

    mf: MatchedFilter  # the probe's (unweighted, cached) matched filter
    taps: np.ndarray | None  # zero-phase conditioning FIR applied to x first
    self_resp: np.ndarray  # weighted complex self response, centred, cut
    beta: float  # RMS bandwidth of the weighted spectrum about its centroid, cycles/sample
    interp_rms: float  # RMS error of interp_peak on the self response, samples
    half_lobe: int  # lags from the peak to where |R| falls below 1/4 of it
    shares: np.ndarray  # expected share of the correlation per sub-band (sums to 1)
    coherent_reach: int  # half width of the phase-coherent search (0: envelope only)
    coherent_rms: float  # RMS error of the coherent interpolation, samples
    f_rms: float  # RMS frequency of the weighted spectrum about 0, cycles/sample

    @property
    def reach(self) -> int:
        """Half length of the conditioning FIR, samples."""
        return 0 if self.taps is None else (len(self.taps) - 1) // 2

    def condition(self, x: np.ndarray) -> np.ndarray:
        """``x`` through the conditioning FIR (weighted, band-limited), time origin kept."""
        return x if self.taps is None else bandlimit(x, self.taps)

    def correlate(self, x: np.ndarray) -> np.ndarray:
        """Analytic correlation of the conditioned ``x``."""
        return self.mf.correlate(self.condition(x))


@functools.lru_cache(maxsize=8)
def _base(probe: Probe, fs: float, block: int) -> _Base:
    """The probe's template, band, band-limiting FIR and PSD at ``fs`` (cached per probe
    by identity and rate: the channels of a recording share them)."""
    from scipy.signal import welch

    h = probe.at_rate(fs)
    mf = MatchedFilter(h, block=block, tail=ANALYTIC_TAIL)
    lo, hi = probe.band_hz()
    nyq = 0.5 * fs
    hi = min(hi, 0.98 * nyq)
    bp = None
    if lo >= _MIN_HIGHPASS_HZ or hi < 0.9 * nyq:
        bp = bandpass_taps(fs, lo if lo >= _MIN_HIGHPASS_HZ else 0.0, hi)
    # ~40 Hz resolution: fine enough to follow a low-frequency noise shelf, short enough
    # that the weighting FIR stays small next to the template.
    nperseg = 1 << max(6, int(round(math.log2(fs / 40.0))))
    nper = min(nperseg, len(h))
    _, S2 = welch(h, fs=fs, nperseg=nper, nfft=nperseg, window="hann", noverlap=nper // 2)
    return _Base(mf, h, (lo, hi), bp, nperseg, S2, nyq)


@functools.lru_cache(maxsize=16)
def _base_response(probe: Probe, fs: float, block: int, w: int) -> np.ndarray:
    """The unweighted self response cut to lags ``+- w`` (cached)."""
    sr = _base(probe, fs, block).mf.self_response
    mid = len(sr) // 2
    out = np.zeros(2 * w + 1, dtype=np.complex128)
    k = min(w, mid)
    out[w - k : w + k + 1] = sr[mid - k : mid + k + 1]
    return out


@functools.lru_cache(maxsize=8)
def _unweighted(probe: Probe, fs: float, block: int, look: int) -> _Filter:
    """The plain matched filter (``weighting="none"``), cached."""
    return _weighted(probe, fs, block, None, look)


def _weighted(probe: Probe, fs: float, block: int, W: np.ndarray | None, look: int) -> _Filter:
    """The probe's filter weighted by ``W`` and band-limited: one zero-phase FIR on ``x``.

    The weighted self response is the unweighted one through the same FIR; the RMS
    bandwidth is that of ``|S|^2`` times the FIR's response on the weights' grid.
    """
    base = _base(probe, fs, block)
    taps = None if W is None else zero_phase_taps(W, 2 * (len(W) - 1))
    if base.bp_taps is not None and W is not None:
        taps = np.convolve(base.bp_taps, taps)
    hw = 0 if taps is None else (len(taps) - 1) // 2
    w = look + 256
    sr = _base_response(probe, fs, block, w + hw)
    if taps is not None:
        sr = np.convolve(sr.real, taps, "valid") + 1j * np.convolve(sr.imag, taps, "valid")
    f = np.fft.rfftfreq(base.nperseg)  # cycles per sample
    p = base.template_psd.copy()
    if taps is not None:
        n_big = base.nperseg * (1 << max(0, math.ceil(math.log2(len(taps) / base.nperseg))))
        H = np.fft.rfft(np.roll(np.pad(taps, (0, n_big - len(taps))), -hw))
        p *= np.abs(H[:: n_big // base.nperseg])
    fc = float(f @ p / p.sum())
    beta = math.sqrt(float(((f - fc) ** 2) @ p / p.sum()))
    edges = _subband_edges(base.band, fs)
    fh = f * fs
    shares = np.array([p[(fh >= a) & (fh < b)].sum() for a, b in itertools.pairwise(edges)])
    shares = shares / max(float(shares.sum()), 1e-300)
    env = np.abs(sr)
    mid = len(sr) // 2
    top = env[mid]
    k = 1
    while mid + k < len(env) and env[mid + k] > 0.25 * top:
        k += 1
    half = max(2, k)
    sr = np.ascontiguousarray(sr)
    # Phase-coherent timing where the real self response has no rival cycle
    # (docs/theory/probes.md): search a quarter carrier period and a sample.
    reach = 0
    coh_rms = 0.0
    if fc > 0 and real_side_ratio(sr, max(2 * half, 8)) <= COHERENT_SIDE:
        reach = int(math.ceil(0.25 / fc)) + 1
        coh_rms = coherent_interp_rms(sr, reach)
    f_rms = math.sqrt(fc**2 + beta**2)
    return _Filter(base.mf, taps, sr, beta, _interp_rms(sr), half, shares, reach, coh_rms, f_rms)


def _interp_rms(sr: np.ndarray, n: int = 16) -> float:
    """RMS error (samples) of :func:`interp_peak` on ``sr`` delayed by ``k / n``."""
    m = len(sr) // 2
    errs = []
    for k in range(n):
        d = k / n
        e = np.abs(_shifted(sr, d))
        i = int(np.argmax(e))
        errs.append(i + interp_peak(e, i)[0] - (m + d))
    return max(float(np.sqrt(np.mean(np.square(errs)))), 1e-6)


def _local_maxima(env: np.ndarray) -> np.ndarray:
    """Indices of local maxima (``>=`` the left neighbour, ``>`` the right one)."""
    if len(env) < 3:
        return np.zeros(0, dtype=np.int64)
    mid = env[1:-1]
    return np.flatnonzero((mid >= env[:-2]) & (mid > env[2:])) + 1


def _empty(fs: float) -> Arrivals:
    return Arrivals.empty(fs=fs, n_bursts=1, detector="template")
