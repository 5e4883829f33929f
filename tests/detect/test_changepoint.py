"""Change-point detector: time origin, sub-sample accuracy, amplitude invariance, structure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rangekit.detect import detect, detect_changepoint, detect_xcorr
from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.signals import Beep
from rangekit.signals.beep import beep_continuous

FS = 44100.0


def _place(n: int, onsets, amps, *, beep: Beep, fs: float = FS) -> np.ndarray:
    """Beeps at exact fractional onsets (continuous-time evaluation, no interpolation)."""
    t = np.arange(n) / fs
    x = np.zeros(n)
    for t0, a in zip(onsets, amps, strict=True):
        x += a * beep_continuous(t - t0 / fs, beep=beep)
    return x


@pytest.mark.parametrize("detector", [detect_changepoint, detect_xcorr])
@pytest.mark.parametrize("onset", [3000.0, 3000.25, 3000.5, 3000.77])
def test_time_origin_and_subsample_onset_noiseless(detector, onset):
    b = Beep()
    x = _place(30000, [onset], [1.0], beep=b)
    arr = detector(x, fs=FS, beep=b)
    assert len(arr) == 1
    tol = 0.02 if detector is detect_changepoint else 0.2
    assert abs(arr.onset[0] - onset) < tol


def test_onset_does_not_shift_with_amplitude():
    """The loud own beep and the faint far beep must be timed alike (60 dB apart)."""
    b = Beep()
    rng = np.random.default_rng(0)
    onsets = [2000.3, 30000.6]
    errs = {}
    for amp in (1.0, 1e-3):
        x = _place(60000, onsets, [amp, amp], beep=b)
        x += 1e-6 * rng.standard_normal(len(x))
        arr = detect_changepoint(x, fs=FS, beep=b)
        errs[amp] = arr.onset - onsets
    np.testing.assert_allclose(errs[1.0], errs[1e-3], atol=0.02)
    assert np.all(np.abs(errs[1.0]) < 0.02)


def test_loud_and_faint_beep_in_one_recording():
    b = Beep()
    rng = np.random.default_rng(1)
    onsets = [4000.4, 40000.9]
    x = _place(70000, onsets, [1.0, 0.01], beep=b)
    # SNR of the faint beep 20 dB (full band).
    x += np.sqrt(0.5 * 0.01**2 / 100) * rng.standard_normal(len(x))
    arr = detect_changepoint(x, fs=FS, beep=b)
    assert len(arr) == 2
    assert abs(arr.onset[0] - onsets[0]) < 0.05
    assert abs(arr.onset[1] - onsets[1]) < 1.5
    assert arr.snr_db[0] > arr.snr_db[1] + 30
    assert np.all(arr.confidence == 1.0)
    # The reported sigma is of the right size for the faint beep.
    assert 0.05 < arr.sigma[1] < 1.5


def test_other_sample_rate_and_other_beep():
    b = Beep(f_hz=18000.0, n_bursts=3, spacing=3000, burst_len=300, taper=30)
    fs = 48000.0
    onset = 1234.56
    x = _place(20000, [onset], [0.3], beep=b, fs=fs)
    arr = detect_changepoint(x, fs=fs, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - onset) < 0.05
    assert arr.burst_onsets.shape == (1, 3)
    spacing_48k = 3000 / 44100 * fs
    np.testing.assert_allclose(np.diff(arr.burst_onsets[0]), spacing_48k, atol=0.05)


def test_silence_gives_empty_result():
    arr = detect_changepoint(np.zeros(44100), fs=FS)
    assert len(arr) == 0 and arr.burst_onsets.shape == (0, 4)
    arr = detect_changepoint(np.random.default_rng(0).standard_normal(44100), fs=FS)
    assert len(arr) == 0


def test_bursts_with_wrong_spacing_are_not_a_beep():
    b_played = Beep(spacing=4000)
    x = _place(40000, [1000.0], [1.0], beep=b_played)
    assert len(detect_changepoint(x, fs=FS, beep=Beep())) == 0
    assert len(detect_changepoint(x, fs=FS, beep=b_played)) == 1


def test_single_burst_or_click_is_not_a_beep():
    b = Beep()
    one = Beep(n_bursts=1)
    x = _place(30000, [1000.0], [1.0], beep=one)
    x[20000] = 1.0  # a click
    assert len(detect_changepoint(x, fs=FS, beep=b)) == 0


def test_a_corrupted_burst_is_rejected_and_the_beep_kept():
    b = Beep()
    x = _place(40000, [1000.0], [1.0], beep=b)
    # Burst 2 is corrupted: an extra tone starts 40 samples before it.
    s = 1000 + 2 * b.spacing - 40
    x[s : s + 60] += 2.0 * np.sin(2 * np.pi * 16000 * np.arange(60) / FS)
    arr = detect_changepoint(x, fs=FS, beep=b)
    assert len(arr) == 1
    assert abs(arr.onset[0] - 1000.0) < 0.05
    assert arr.confidence[0] == 0.75
    assert np.isnan(arr.burst_onsets[0, 2])


def test_late_echo_of_a_beep_is_dropped():
    b = Beep()
    # An echo 30 ms later (after each burst has ended) at half amplitude.
    x = _place(40000, [1000.0, 1000.0 + 1323.0], [1.0, 0.5], beep=b)
    arr = detect_changepoint(x, fs=FS, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - 1000.0) < 0.05


def test_first_path_wins_over_a_stronger_reflection():
    """Two reflections adding in phase 80 samples after a weaker direct path."""
    b = Beep()
    rng = np.random.default_rng(3)
    x = _place(40000, [1000.0, 1080.0], [1.0, 2.0], beep=b)
    x += np.sqrt(0.5 / 10) * rng.standard_normal(len(x))  # 10 dB below the direct path
    arr = detect_changepoint(x, fs=FS, beep=b)
    assert len(arr) == 1 and abs(arr.onset[0] - 1000.0) < 2.0


def test_detect_dispatch_and_errors():
    x = np.zeros(10000)
    assert len(detect(x, fs=FS, detector="xcorr")) == 0
    with pytest.raises(InvalidParameterError, match=r"method=.nope. must be one of"):
        detect(x, fs=FS, detector="nope")
    with pytest.raises(IncompatibleInputError, match="too low"):
        detect_changepoint(x, fs=16000.0)
    with pytest.raises(InvalidParameterError, match="1-D"):
        detect_changepoint(np.zeros((10, 2)), fs=FS)
    with pytest.raises(InvalidParameterError, match="NaN"):
        detect_changepoint(np.full(100, np.nan), fs=FS)


# --- start-up: the detector's helpers without scipy.signal, numpy.ma or numba (issue 20) ----


@pytest.mark.parametrize("fs", [8000.0, 44100.0, 48000.0, 192000.0])
@pytest.mark.parametrize(
    "band", [(14000.0, 18000.0), (0.0, 3000.0), (300.0, 3500.0), (3000.0, 1e9), (0.0, 1e9)]
)
def test_bandpass_taps_equal_scipy_firwin(fs, band):
    """The numpy Kaiser window method gives scipy.signal.firwin's taps to 2.3e-16."""
    from scipy.signal import firwin, kaiser_beta

    from rangekit.detect import condition as C

    lo, hi = band[0], min(band[1], 0.45 * fs)
    if lo >= hi:
        pytest.skip("band beyond Nyquist")
    h = C.bandpass_taps(fs, lo, hi)
    beta = kaiser_beta(C.DEFAULT_ATTEN_DB)
    assert C._kaiser_beta(C.DEFAULT_ATTEN_DB) == beta
    for n, cut, pz in [(len(h), [0.1 * fs, 0.3 * fs], False), (101, [0.2 * fs], True),
                       (301, [0.05 * fs], False), (9, [0.1 * fs, 0.2 * fs], True)]:  # fmt: skip
        ref = firwin(n, cut, window=("kaiser", beta), fs=fs, pass_zero=pz)
        got = C._firwin_kaiser(n, cut, beta, fs, pass_zero=pz)
        assert np.max(np.abs(got - ref)) <= 4e-16 * np.max(np.abs(ref))


@pytest.mark.parametrize("n", [1, 2, 3, 8, 345, 1000])
@pytest.mark.parametrize("q", [0.0, 10.0, 20.0, 50.0, 99.9, 100.0])
def test_percentile_equals_numpy(n, q):
    from rangekit.detect.condition import percentile

    rng = np.random.default_rng(n)
    a = rng.exponential(size=n)
    assert percentile(a, q) == np.percentile(a, q)
    b = rng.exponential(size=(5, n))
    np.testing.assert_array_equal(percentile(b, q, axis=1), np.percentile(b, q, axis=1))


def test_a_short_recording_imports_neither_scipy_signal_nor_numba(tmp_path):
    """Detecting on one exchange (the numpy path) loads no heavy module."""
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\n"
        "from rangekit.detect import detect_changepoint\n"
        "from rangekit.sim import render_beepbeep, pair_devices\n"
        "sim = render_beepbeep(pair_devices(2.0), snr_db=20, rng=1)\n"
        "before = set(sys.modules)\n"
        "arr = detect_changepoint(sim.recordings[0], fs=44100.0)\n"
        "assert len(arr) == 2, arr\n"
        "new = set(sys.modules) - before\n"
        "bad = sorted(m for m in new if m.split('.')[0] == 'numba' or m.startswith("
        "('scipy.signal', 'scipy.stats', 'numpy.ma')))\n"
        "print(' '.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


@pytest.mark.parametrize("subtype", ["PCM_16", "PCM_24", "PCM_32", "FLOAT", "DOUBLE"])
def test_integer_pcm_is_read_into_float32_exactly(tmp_path, subtype):
    """read_audio decodes into float32 where float32 holds every sample (the detector then
    reads it without a float64 copy), with the float64 values; else into float64."""
    from rangekit.io.audio import load_devices, read_audio, write_audio

    x = np.random.default_rng(0).uniform(-0.9, 0.9, (2000, 2))
    f = tmp_path / f"x_{subtype}.wav"
    write_audio(f, x, fs=FS, subtype=subtype)
    auto, _ = read_audio(f)
    wide, _ = read_audio(f, dtype="float64")
    assert auto.dtype == (np.float64 if subtype in ("PCM_32", "DOUBLE") else np.float32)
    np.testing.assert_array_equal(auto.astype(np.float64), wide)
    assert load_devices([f])[0].x.dtype == np.float64
    with pytest.raises(InvalidParameterError, match="dtype"):
        read_audio(f, dtype="int16")


def test_a_float_file_with_nan_is_refused(tmp_path):
    import soundfile as sf

    from rangekit.errors import AudioFormatError
    from rangekit.io.audio import read_audio

    x = np.zeros((100, 1), dtype=np.float32)
    x[50] = np.nan
    sf.write(tmp_path / "nan.wav", x, 44100, subtype="FLOAT")
    with pytest.raises(AudioFormatError, match="NaN"):
        read_audio(tmp_path / "nan.wav")


def _click_before_bursts(before: int, *, seed: int, noise: float = 0.001) -> np.ndarray:
    """A beep (peak 0.5) at 20000.3 with a saturated 3-sample click ``before`` samples
    before each burst, in white noise; samples clipped to +-1."""
    b = Beep()
    x = 0.5 / 0.9 * _place(60000, [20000.3], [1.0], beep=b)
    x += noise * np.random.default_rng(seed).standard_normal(len(x))
    for k in range(b.n_bursts):
        p = 20000 + k * b.spacing - before
        x[p : p + 3] = 1.0
    return np.clip(x, -1.0, 1.0)


@pytest.mark.parametrize("before", [60, 100, 300])
@pytest.mark.parametrize("compiled", [False, True])
def test_a_saturated_click_before_each_burst_does_not_hide_the_beep(before, compiled, monkeypatch):
    """A click's broadband energy raised a change point whose frames ran into the beep's,
    so the beep raised none (60-100 samples before: no arrival at all). The clicks are
    left out of the band energy (``click_mask``) and an edge at a search window's late end
    is re-anchored on: the beep is found, on both paths, where it is without clicks
    (measured within 0.1 samples)."""
    from rangekit.detect import _edge_kernels as K

    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0 if compiled else 10**12)
    for seed in range(2):
        arr = detect_changepoint(_click_before_bursts(before, seed=seed), fs=FS)
        assert len(arr) == 1, (before, seed)
        assert abs(arr.onset[0] - 20000.3) < 0.2  # measured <= 0.1
        assert arr.confidence[0] == 1.0


def test_a_click_inside_the_fit_window_is_found_and_flagged_clipped():
    """20 samples before each burst the click lies in the edge fit's window: the fit
    leaves its samples out and the arrival is flagged ``clipped`` (measured 0.05)."""
    arr = detect_changepoint(_click_before_bursts(20, seed=0), fs=FS)
    assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.2
    assert "clipped" in arr.flag_names(0)


def test_click_mask_marks_lone_short_clipped_runs_not_a_clipped_beep():
    """Clicks are short runs of clipped samples with no other clipped sample near: a
    clipped beep (every crest at the rail) has none, a click among them is not one, and a
    run longer than ``CLICK_MAX_S`` is not a click."""
    from rangekit.detect.changepoint import CLICK_GAP_S, CLICK_MAX_S, click_mask
    from rangekit.detect.condition import clip_mask
    from rangekit.signals import beep_waveform

    b = Beep()
    x = np.zeros(30000)
    x[1000 : 1000 + b.duration_samples] = np.clip(3.0 * beep_waveform(b), -1.0, 1.0)
    clipped = clip_mask(x)
    assert clipped.sum() > 1000 and not click_mask(clipped, fs=FS).any()
    m = np.zeros(2000, dtype=bool)
    gap, longest = round(CLICK_GAP_S * FS), round(CLICK_MAX_S * FS)
    m[500 : 500 + longest] = True  # the longest click
    m[1000 : 1000 + longest + 1] = True  # one sample too long
    m[1500:1503] = True
    m[1502 + gap] = True  # another clipped sample just within the gap: not alone
    got = click_mask(m, fs=FS)
    assert np.flatnonzero(got).tolist() == list(range(498, 500 + longest + 2))
    m[1502 + gap] = False
    m[1503 + gap] = True  # one further: both are alone
    assert click_mask(m, fs=FS)[1500:1503].all()


def _nlos(noise: float, *, seed: int, lag: int = 150) -> np.ndarray:
    """A direct path of peak 0.05 at 20000 and a reflection 10 times stronger ``lag``
    samples later, in white noise."""
    b = Beep()
    x = _place(60000, [20000.0, 20000.0 + lag], [0.05 / 0.9, 0.5 / 0.9], beep=b)
    return x + noise * np.random.default_rng(seed).standard_normal(len(x))


@pytest.mark.parametrize("lag", [150, 300])
def test_a_direct_path_too_weak_to_time_before_a_reflection_is_flagged(lag):
    """NLOS: the direct path 20 dB below a reflection ``lag`` samples later, in noise of
    0.05 (the direct path about 0 dB in band, too weak for the edge fit): the onset is the
    reflection's, and the frames just before it stand 9-13 dB above the level before in
    every burst (measured): ``ambiguous_first_path``. At noise 0.01 the direct
    path is timed and nothing is flagged."""
    for seed in range(3):
        arr = detect_changepoint(_nlos(0.05, seed=seed, lag=lag), fs=FS)
        assert len(arr) >= 1
        assert abs(arr.onset[0] - 20000.0 - lag) < 3.0  # the reflection (measured 1)
        assert "ambiguous_first_path" in arr.flag_names(0), (lag, seed)
        arr = detect_changepoint(_nlos(0.01, seed=seed, lag=lag), fs=FS)
        assert abs(arr.onset[0] - 20000.0) < 1.0 and arr.flags[0] == 0


def test_the_last_frames_test_does_not_flag_a_beep_in_noise():
    """The one-by-one test of the frames before an onset in white noise only: over 30
    beeps at SNRs of 10-40 dB the largest frame (the smallest over the bursts) stood 1.4
    dB above the level before (measured), under PRE_LAST_DB; none is flagged."""
    from rangekit.detect import changepoint as cp

    b = Beep()
    worst = -np.inf
    for seed in range(30):
        noise = (0.003, 0.01, 0.03)[seed % 3]
        x = _place(50000, [20000.4], [0.3 / 0.9], beep=b)
        x += noise * np.random.default_rng(seed).standard_normal(len(x))
        arr = detect_changepoint(x, fs=FS, beep=b)
        assert len(arr) == 1 and "ambiguous_first_path" not in arr.flag_names(0)
        n_win, hop, e, _, _ = cp._candidates(
            x, fs=FS, beep=b, win_s=cp.WIN_S, hop_s=cp.HOP_S, threshold_db=6.0, rise_db=10.0
        )
        r = cp._last_frames_ratio(
            e, float(arr.onset[0]), hop=hop, n_win=n_win, fs=FS, spacing=5000.0, n=4
        )
        worst = max(worst, 10 * np.log10(r.max()))
    print("worst", worst)
    assert 0.0 < worst < cp.PRE_LAST_DB  # measured 1.4


@pytest.mark.parametrize("compiled", [False, True])
def test_a_re_anchored_edge_on_a_later_burst_is_not_a_new_beep(compiled, monkeypatch):
    """A change point just before a found beep's second burst, its edge at the search
    window's late end, was re-anchored on that burst and timed bursts 1-3 as a beep one
    burst spacing (5000 samples) late, chosen over the true beep whose first burst is
    clipped (tests/data/realistic: the realistic corpus' seed 11, exchange 59, p90 of
    the corpus 2.4 -> 9.4 cm). The true onset is 3247.2."""
    import soundfile as sf

    from rangekit.detect import _edge_kernels as K

    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0 if compiled else 10**12)
    path = Path(__file__).parents[1] / "data" / "realistic" / "clipped_first_burst.flac"
    x, fs = sf.read(path)
    arr = detect_changepoint(x, fs=fs)
    assert len(arr) == 1
    assert abs(arr.onset[0] - 3247.2) < 0.5  # measured 0.1


def _beep_and_burst(seed: int, lone_at: float, *, amp: float = 1.0) -> np.ndarray:
    """A beep (peak 0.5) at 20000.3 and one burst of the beep's shape (peak ``0.5 amp``)
    at ``lone_at``, in white noise of 0.001."""
    x = 0.5 / 0.9 * _place(60000, [20000.3], [1.0], beep=Beep())
    x += amp * 0.5 / 0.9 * _place(60000, [lone_at], [1.0], beep=Beep(n_bursts=1))
    return x + 0.001 * np.random.default_rng(seed).standard_normal(len(x))


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("lone_at", [40000.3, 15000.3])
def test_a_burst_one_spacing_beyond_the_beep_flags_a_shifted_beep(lone_at, compiled, monkeypatch):
    """Bursts at t0 .. t0 + 3s and a lone burst as strong at t0 + 4s (or t0 - s) fit a
    beep at t0 + s (t0 - s) as well as the true one at t0: which one the detector takes
    is chance (measured: one spacing late in seeds 1-3, early in seed 0; the others
    right). The arrival is flagged ``ambiguous_first_path`` (every seed, measured) or,
    at the least, right: never a shifted beep without a flag."""
    from rangekit.detect import _edge_kernels as K

    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0 if compiled else 10**12)
    spacing = Beep().spacing
    for seed in range(4):
        arr = detect_changepoint(_beep_and_burst(seed, lone_at), fs=FS)
        assert len(arr) == 1
        off = arr.onset[0] - 20000.3
        assert min(abs(off), abs(abs(off) - spacing)) < 0.1  # the beep, or shifted
        assert abs(off) < 0.1 or "ambiguous_first_path" in arr.flag_names(0), (seed, off)
        assert "ambiguous_first_path" in arr.flag_names(0)


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("kind", ["clipped", "masked"])
def test_a_clipped_or_masked_first_burst_and_a_burst_after_the_beep_are_flagged(
    kind, compiled, monkeypatch
):
    """The same with the beep's first burst clipped (three times as loud, the recording
    clipped at 0.6 after the noise) or masked (a tone of 0.3 at the beep's frequency over
    it, 1000 samples either side, which partly cancels it: its band energy rises 0.2-0.8
    dB): bursts 1-3 and the lone burst make the better beep, one spacing late (measured:
    every seed clipped, 3 of 4 masked). Flagged (every seed, measured) or right."""
    from rangekit.detect import _edge_kernels as K

    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0 if compiled else 10**12)
    for seed in range(4):
        rng = np.random.default_rng(seed)
        x = _beep_and_burst(seed, 40000.3)
        if kind == "clipped":
            x[19990:20500] *= 3.0
            x = np.clip(x, -0.6, 0.6)
        else:
            t = np.arange(19000, 21500)
            tone = np.sin(2 * np.pi * Beep().f_hz * t / FS + rng.uniform(0.0, 2 * np.pi))
            x[t] += 0.3 * tone * np.hanning(len(t))
        arr = detect_changepoint(x, fs=FS)
        assert len(arr) == 1
        off = arr.onset[0] - 20000.3
        assert abs(off) < 0.5 or "ambiguous_first_path" in arr.flag_names(0), (seed, off)
        assert "ambiguous_first_path" in arr.flag_names(0)


def test_a_burst_off_the_spacing_grid_does_not_flag():
    """The same lone burst 20-200 samples off the place one spacing after the last
    burst: no beep fits it (the bursts' allowed scatter is 2 samples + 4 sigma + 200 ppm
    of the spacing), so nothing is ambiguous: right, no flag (measured from 10 samples
    off on; 3 and 6 samples off are flagged)."""
    for off in (20.0, 60.0, 200.0):
        for seed in range(2):
            arr = detect_changepoint(_beep_and_burst(seed, 40000.3 + off), fs=FS)
            assert len(arr) == 1 and abs(arr.onset[0] - 20000.3) < 0.1
            assert arr.flags[0] == 0, (off, seed, arr.flag_names(0))


@pytest.mark.parametrize("amps", [(0.3, 0.3), (0.03, 0.9), (0.9, 0.03)])
def test_two_beeps_on_one_spacing_grid_are_both_kept_unflagged(amps):
    """A beep starting one spacing after another beep's last burst (a far beep, then the
    own beep just after it, or the other way round): groups at every spacing between
    them mix the two beeps' bursts. Resolved pair by pair, one of the mixed groups stayed
    and a beep was lost (measured: 4 of 6 seeds at equal levels, every seed with the two
    30 dB apart); resolved together, the two beeps explain every burst once. The burst
    beyond each is the other's, which explains it, so neither is flagged (without that
    rule both were at equal levels, the weaker one with the two 30 dB apart)."""
    for seed in range(3):
        x = _place(80000, [20000.3, 40000.3], list(amps), beep=Beep())
        x += 0.001 * np.random.default_rng(seed).standard_normal(len(x))
        arr = detect_changepoint(x, fs=FS)
        assert len(arr) == 2, (seed, arr.onset)
        np.testing.assert_allclose(arr.onset, [20000.3, 40000.3], atol=0.5)  # measured 0.2
        assert np.all(arr.flags == 0), [arr.flag_names(i) for i in range(2)]


def test_a_plain_beep_in_noise_is_not_flagged():
    """A beep in white noise at in-band SNRs of about 10-40 dB, nothing else: no flag."""
    b = Beep()
    for seed in range(12):
        noise = (0.001, 0.003, 0.01, 0.03)[seed % 4]
        x = _place(50000, [20000.4 + 37 * seed], [0.3 / 0.9], beep=b)
        x += noise * np.random.default_rng(seed).standard_normal(len(x))
        arr = detect_changepoint(x, fs=FS, beep=b)
        assert len(arr) == 1 and abs(arr.onset[0] - 20000.4 - 37 * seed) < 0.5
        assert arr.flags[0] == 0, (seed, arr.flag_names(0))


def _reverberant(seed: int, *, rt60_s: float, n: int = 70000) -> np.ndarray:
    """A beep (peak 0.3) at 10000.3 through a synthetic room: the direct path plus an
    exponentially decaying white-noise tail from 90 samples on (``rt60_s``, as much
    energy as the direct path), in white noise of 0.001."""
    rng = np.random.default_rng(seed)
    x = _place(n, [10000.3], [0.3], beep=Beep())
    m = int(min(rt60_s, 1.0) * FS)
    h = rng.standard_normal(m) * 10 ** (-3.0 * np.arange(m) / FS / rt60_s)
    h[:90] = 0.0
    h /= np.sqrt(np.sum(h**2))
    h[0] += 1.0
    size = 1 << int(np.ceil(np.log2(n + m)))
    y = np.fft.irfft(np.fft.rfft(x, size) * np.fft.rfft(h, size), size)[:n]
    return y + 0.001 * rng.standard_normal(n)


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("rt60_s", [0.3, 0.8])
def test_a_beep_in_a_reverberant_synthetic_room_is_not_flagged(rt60_s, compiled, monkeypatch):
    """Each burst's reverberant tail fills the 5000 samples to the next burst place and
    beyond the last one; it decays there, it does not rise like a burst, so the whole-
    spacing test leaves the beep alone: right, no flag (with ``expected=1`` dropping a
    spurious group in the tail, flagged ``low_snr`` and ``inconsistent_bursts``)."""
    from rangekit.detect import _edge_kernels as K

    monkeypatch.setattr(K, "NUMBA_MIN_SAMPLES", 0 if compiled else 10**12)
    for seed in range(4):
        arr = detect_changepoint(_reverberant(seed, rt60_s=rt60_s), fs=FS, expected=1)
        assert len(arr) == 1 and abs(arr.onset[0] - 10000.3) < 0.5  # measured <= 0.05
        assert arr.flags[0] == 0, (seed, arr.flag_names(0))
