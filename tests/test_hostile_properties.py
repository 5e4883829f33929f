"""Property tests (hypothesis, seeded): public detection, ranging and reading functions
given arbitrary arguments raise only the RangekitError family and leak no warnings
(issue 17). About 6,200 examples in all; every run draws the same ones (derandomize)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from rangekit.errors import RangekitError  # noqa: E402

SETTINGS = dict(
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

#: Any argument value a caller might pass: numbers from tiny to absurd, non-finite,
#: wrong types.
ANY = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([None, True, False, "x", "", [], [1.0], (2, 3), 0, 1, -1, 1e300, 5e-324]),
)
#: Plausible-but-edgy positive numbers (near the defaults, and out to the extremes).
SCALE = st.one_of(
    st.floats(min_value=1e-6, max_value=1e6), st.sampled_from([0.0, -1.0, math.nan, 1e300])
)


def _quietly(f, *a, **k):
    """Call f; only RangekitError may come out, and no warning may be emitted."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return f(*a, **k)
        except RangekitError:
            return None


@st.composite
def signals(draw, max_len=3000):
    """Short signals: silence, noise, a beep, with spikes, extremes or a wrong shape."""
    from rangekit.signals import Beep, beep_waveform

    n = draw(st.integers(0, max_len))
    kind = draw(st.sampled_from(["zeros", "noise", "beep", "spike", "huge", "2d", "list"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    x = np.zeros(n) if kind == "zeros" else 1e-3 * rng.standard_normal(n)
    if kind == "beep" and n > 0:
        b = beep_waveform(Beep(n_bursts=2, spacing=600))[:n]
        x[: len(b)] += b
    if kind == "spike" and n > 0:
        x[rng.integers(n)] = draw(st.sampled_from([1.0, 1e6, 1e100, 1e300, -1e300]))
    if kind == "huge":
        x = x * draw(st.sampled_from([1e50, 1e150, 1e308]))
    if kind == "2d":
        return x.reshape(1, -1) if n else np.zeros((2, 2))
    if kind == "list":
        return x.tolist()
    return x


FS = st.one_of(st.sampled_from([44100.0, 48000.0, 8000.0]), ANY)


@settings(max_examples=900, **SETTINGS)
@given(
    x=signals(),
    fs=FS,
    win=st.one_of(st.just(128 / 44100), SCALE),
    hop=st.one_of(st.just(32 / 44100), SCALE),
    thr=st.one_of(st.just(6.0), ANY),
    rise=st.one_of(st.just(10.0), ANY),
    expected=st.one_of(st.none(), ANY),
)
def test_detect_changepoint(x, fs, win, hop, thr, rise, expected):
    from rangekit.detect import detect_changepoint
    from rangekit.signals import Beep

    beep = Beep(n_bursts=2, spacing=600)
    _quietly(
        detect_changepoint,
        x,
        fs=fs,
        beep=beep,
        win_s=win,
        hop_s=hop,
        threshold_db=thr,
        rise_db=rise,
        expected=expected,
    )


@settings(max_examples=900, **SETTINGS)
@given(
    x=signals(),
    fs=FS,
    thr=st.one_of(st.just(20.0), ANY),
    max_beeps=st.one_of(st.none(), ANY),
    conf=st.one_of(st.just(0.75), ANY),
)
def test_detect_xcorr(x, fs, thr, max_beeps, conf):
    from rangekit.detect import detect_xcorr
    from rangekit.signals import Beep

    beep = Beep(n_bursts=2, spacing=600)
    _quietly(
        detect_xcorr,
        x,
        fs=fs,
        beep=beep,
        threshold_db=thr,
        max_beeps=max_beeps,
        min_confidence=conf,
    )


@settings(max_examples=300, **SETTINGS)
@given(x=signals(), detector=st.one_of(st.sampled_from(["changepoint", "xcorr"]), ANY))
def test_detect_dispatch(x, detector):
    from rangekit.detect import detect
    from rangekit.signals import Beep

    _quietly(detect, x, fs=44100.0, beep=Beep(n_bursts=2, spacing=600), detector=detector)


@settings(max_examples=1200, **SETTINGS)
@given(
    f_hz=st.one_of(st.just(16000.0), ANY),
    n_bursts=st.one_of(st.just(4), ANY),
    spacing=st.one_of(st.just(5000), ANY),
    burst_len=st.one_of(st.just(441), ANY),
    taper=st.one_of(st.just(22), ANY),
    amplitude=st.one_of(st.just(0.9), ANY),
    fs=st.one_of(st.just(44100.0), ANY),
)
def test_beep(f_hz, n_bursts, spacing, burst_len, taper, amplitude, fs):
    from rangekit.signals import Beep, beep_waveform, check_beep_fits

    kw = dict(f_hz=f_hz, n_bursts=n_bursts, spacing=spacing, burst_len=burst_len)
    b = _quietly(Beep, **kw, taper=taper, amplitude=amplitude, fs=fs)
    if b is not None:
        _quietly(check_beep_fits, b, fs=fs)
        if b.duration_samples <= 200_000:
            w = _quietly(beep_waveform, b)
            assert w is None or np.all(np.isfinite(w))


@st.composite
def arrivals(draw, n):
    from rangekit.types import Arrivals

    k = draw(st.integers(0, n + 1))
    onset = draw(
        st.lists(
            st.one_of(st.floats(-1e6, 1e7), st.sampled_from([math.nan, math.inf, 1e300])),
            min_size=k,
            max_size=k,
        )
    )
    sig = draw(st.one_of(st.just(0.1), st.sampled_from([0.0, -1.0, math.nan, 1e300])))
    fs = draw(st.one_of(st.just(44100.0), st.sampled_from([0.0, -1.0, math.nan, 1e300])))
    z = np.zeros(k)
    return Arrivals(np.array(onset, dtype=float), fs, z + sig, z + 30, z + 1, np.zeros((k, 4)))


@settings(max_examples=1500, **SETTINGS)
@given(
    data=st.data(),
    n=st.integers(0, 4),
    c=st.one_of(st.just(343.0), ANY),
    sd=st.one_of(st.just(0.0), ANY, st.lists(ANY, max_size=5)),
    ppm=st.one_of(st.just(30.0), ANY),
)
def test_range_beepbeep(data, n, c, sd, ppm):
    from rangekit.ranging import range_beepbeep

    arrs = [_quietly(data.draw, arrivals(n)) for _ in range(n)]
    if any(a is None for a in arrs):
        return  # Arrivals refused its own arguments (a RangekitError)
    res = _quietly(range_beepbeep, arrs, speed_m_s=c, self_distance_m=sd, clock_ppm=ppm)
    if res is not None:
        for r in res.ranges:
            assert math.isfinite(r.distance_m) and math.isfinite(r.sigma_m) and r.sigma_m >= 0


@settings(max_examples=800, **SETTINGS)
@given(
    text=st.one_of(
        st.text(max_size=200),
        st.recursive(
            st.one_of(st.none(), st.booleans(), st.floats(), st.integers(), st.text(max_size=5)),
            lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=4), c, max_size=4),
            max_leaves=30,
        ).map(lambda o: __import__("json").dumps(o)),
    )
)
def test_guarded_json_and_sidecar_values(text):
    from rangekit.batch import _sidecar_values
    from rangekit.io.guard import parse_json

    obj = _quietly(parse_json, text, name="x.json")
    if isinstance(obj, dict):
        for scheme in (None, "beepbeep", "oneway", "echo"):
            _quietly(_sidecar_values, obj, scheme)


@settings(max_examples=300, **SETTINGS)
@given(
    x=signals(max_len=20000),
    fs=st.one_of(st.just(192000.0), ANY),
    period=st.one_of(st.none(), SCALE),
    lat=st.one_of(st.just(0.0), ANY),
    hi=st.one_of(st.just(15.0), ANY),
    c=st.one_of(st.none(), ANY),
    t=st.one_of(st.just(20.0), ANY),
)
def test_range_oneway(x, fs, period, lat, hi, c, t):
    from rangekit.ranging.ultrasonic import range_oneway

    kw = dict(period_s=period, latency_s=lat, max_range_m=hi, speed_m_s=c, temp_c=t)
    _quietly(range_oneway, x, fs=fs, tx=None, rx=None, **kw)


@settings(max_examples=300, **SETTINGS)
@given(
    x=signals(max_len=20000),
    fs=st.one_of(st.just(192000.0), ANY),
    lo=st.one_of(st.just(0.15), ANY),
    hi=st.one_of(st.just(6.0), ANY),
    t=st.one_of(st.just(20.0), ANY),
)
def test_range_echo(x, fs, lo, hi, t):
    from rangekit.ranging.ultrasonic import range_echo

    _quietly(range_echo, x, fs=fs, min_range_m=lo, max_range_m=hi, temp_c=t)


def test_range_echo_shorter_than_one_period():
    """Was an IndexError in the windows loop (the CLI and batch refuse such files first,
    rangekit.io.audio.check_period); now the library says it too."""
    from rangekit.errors import IncompatibleInputError
    from rangekit.ranging.ultrasonic import range_echo, range_oneway

    for fn in (range_echo, range_oneway):
        with pytest.raises(IncompatibleInputError, match="shorter than half a period"):
            fn(np.zeros(2), fs=192000.0, period_s=1.0)
