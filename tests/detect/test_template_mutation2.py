"""detect_template's helpers against closed forms and independent references (issue 21,
the mutation check, second round: ``benchmarks/mutation.py``, ``docs/evidence.md``).

Most tests call a helper of ``rangekit/detect/template.py`` directly, on a synthetic filter
(a Gaussian-windowed analytic tone as the self response, known in closed form at any lag)
or on a real probe's filter against numpy/scipy computations of what its docstring states:
the main-lobe fit and its unexplained and odd shares, the CLEAN steps and their window,
the first-order side-lobe pull against the exact peak shift, a tail's decay line, the
cluster and local-floor windows, the filter's RMS bandwidth, sub-band shares, half lobe,
coherent reach and template spectrum, the FIR's real response, and, on whole detections,
the transducer term and the SNR, confidence and flags each by its rule. Seeded, fast
(about 5 s).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.signal import welch

import rangekit.detect.template as T
from rangekit.detect.matched import (
    DEFAULT_BLOCK,
    interp_peak,
    weighting_response,
    welch_spectra,
)
from rangekit.signals.probe import linear_sweep

FS = 44100.0

# --- a synthetic filter: R(l) = exp(-l^2 / 2 s^2) exp(2 pi i f0 l), lags +- M --------------

S, F0, M = 5.0, 0.12, 300
K = 9  # |R| falls to 1/4 at l = s sqrt(2 ln 4) = 8.3: the first lag at or below is 9


def R_an(t):
    """The synthetic self response at any (real) lag ``t``."""
    t = np.asarray(t, dtype=float)
    return np.exp(-0.5 * (t / S) ** 2) * np.exp(2j * np.pi * F0 * t)


def _wf(m: int = M, half_lobe: int = K) -> T._Filter:
    R = R_an(np.arange(-m, m + 1.0))
    return T._Filter(None, None, R, 0.03, 0.0, half_lobe, np.ones(8) / 8, 0, 0.0, F0)


N_C = 2000
L = np.arange(float(N_C))
J, D = 1000, 0.3
ALPHA = 0.7 * np.exp(0.4j)


def _path(amp, at, n=L):
    return amp * R_an(n - at)


# --- the main-lobe fit (_lobe_fit, _shape) ------------------------------------------------


def _eps_reference(c, j, d, floor):
    """1 - rho^2 - noise share over the main lobe j +- K, the reference R(l - j - d)
    evaluated in closed form."""
    core = np.arange(j - K, j + K + 1)
    r, s = R_an(core - j - d), c[core]
    rr, ss = np.vdot(r, r).real, np.vdot(s, s).real
    rho2 = abs(np.vdot(r, s)) ** 2 / (rr * ss)
    return max(0.0, 1.0 - rho2 - (2 * K + 1) * 2.0 * floor**2 / ss)


def test_half_lobe_of_the_synthetic_filter():
    R = np.abs(R_an(np.arange(0.0, 20.0)))
    assert R[K] <= 0.25 < R[K - 1]


def test_a_path_alone_leaves_nothing_unexplained():
    """``c`` exactly ``alpha R(l - j - d)``: eps 0 (to rounding), no rival; the noise share
    only lowers it (clipped at 0)."""
    wf = _wf()
    c = _path(ALPHA, J + D)
    eps, rival = T._shape(c, J, D, wf, 0.0)
    assert eps < 1e-12 and not rival  # measured 2.2e-16
    assert T._shape(c, J, D, wf, 0.01) == (0.0, False)


@pytest.mark.parametrize("b", [0.2, 0.45, 0.55])
@pytest.mark.parametrize("off", [5, 14, -11])
@pytest.mark.parametrize("floor", [0.0, 0.004])
def test_unexplained_fraction_is_one_minus_rho2_minus_the_noise_share(b, off, floor):
    """A second path ``b`` times the first, ``off`` lags away: ``_shape``'s eps is ``1 -
    rho^2 - (2 K + 1) 2 floor^2 / ss`` over the main lobe ``j +- K`` (computed here with
    the closed-form reference), to 1e-12."""
    wf = _wf()
    c = _path(ALPHA, J + D) + _path(b * ALPHA, J + D + off)
    eps, _ = T._shape(c, J, D, wf, floor)
    want = _eps_reference(c, J, D, floor)
    assert want > 1.5e-3 or floor > 0  # the second path is seen (measured >= 3.1e-3)
    assert eps == pytest.approx(want, abs=1e-12, rel=1e-9)


@pytest.mark.parametrize(("b", "rival"), [(0.3, False), (0.45, False), (0.55, True), (0.6, True)])
def test_a_rival_path_within_two_lobes_is_at_least_half_the_height(b, rival):
    """A second path 14 lags behind (beyond the main lobe K = 9, within 2 K): a rival when
    the residual's peak reaches AMBIGUOUS_REL (0.5) of the path's height (the residual's
    peak is about b: 0.45 is not, 0.55 is)."""
    c = _path(ALPHA, J + D) + _path(b * ALPHA, J + D + 14)
    assert T._shape(c, J, D, _wf(), 0.0)[1] is rival


def test_a_rival_beyond_two_lobes_is_not_seen():
    """The residual is read over ``j +- 2 K`` only: a path as strong 3 K away is no rival."""
    c = _path(ALPHA, J + D) + _path(ALPHA, J + D + 3 * K)
    assert T._shape(c, J, D, _wf(), 0.0)[1] is False


def test_the_lobe_fit_needs_its_window_inside_c_and_the_self_response():
    """``_lobe_fit`` reads ``c[j - half : j + half + 1]`` and the self response's ``+- half``
    lags: None one sample short either way, a fit at the limits."""
    wf = _wf()
    h = 2 * K
    c = _path(ALPHA, J + D)
    assert T._lobe_fit(c[J - h :], h, D, wf, h) is not None
    assert T._lobe_fit(c[J - h + 1 :], h - 1, D, wf, h) is None
    n = J + h + 1  # c ends just after the window
    assert T._lobe_fit(c[:n], J, D, wf, h) is not None
    assert T._lobe_fit(c[: n - 1], J, D, wf, h) is None
    assert T._lobe_fit(c, J, D, _wf(m=h + 1), h) is not None
    assert T._lobe_fit(c, J, D, _wf(m=h), h) is None
    assert T._lobe_fit(np.zeros(N_C, dtype=complex), J, D, wf, h) is None  # no energy
    assert T._shape(np.zeros(N_C, dtype=complex), J, D, wf, 0.0) == (0.0, False)


def test_the_lobe_fit_returns_the_window_and_the_main_lobes_energies():
    """``(R, seg, rr, ss, <r, s>)``: the shifted self response and ``c`` over ``j +- half``,
    and the energies and cross term over the main lobe ``j +- K``."""
    wf = _wf()
    h = K + 18
    c = _path(ALPHA, J + D) + _path(0.3, J + 12)
    R, seg, rr, ss, rs = T._lobe_fit(c, J, D, wf, h)
    lag = np.arange(-h, h + 1.0)
    np.testing.assert_allclose(R, R_an(lag - D), atol=1e-12)
    np.testing.assert_array_equal(seg, c[J - h : J + h + 1])
    core = np.arange(J - K, J + K + 1)
    r, s = R_an(core - J - D), c[core]
    assert rr == pytest.approx(np.vdot(r, r).real, rel=1e-12)
    assert ss == pytest.approx(np.vdot(s, s).real, rel=1e-12)
    assert rs == pytest.approx(np.vdot(r, s), rel=1e-12)


# --- the residual's odd part (_odd_eps) ---------------------------------------------------


def _odd_reference(c_at, j, d, floor):
    """``_odd_eps`` by its docstring, with the analytic ``c`` read at the reflected lags."""
    tau = j + d
    core = np.arange(j - K, j + K + 1.0)
    r, s = R_an(core - tau), c_at(core)
    rr, ss = np.vdot(r, r).real, np.vdot(s, s).real
    alpha = np.vdot(r, s) / rr
    p = alpha / np.conj(alpha)

    def e(t):
        return c_at(t) - alpha * R_an(t - tau)

    eo = 0.5 * (e(core) - p * np.conj(e(2 * tau - core)))
    return max(0.0, np.vdot(eo, eo).real / ss - 0.5 * (2 * K + 1) * 2.0 * floor**2 / ss)


@pytest.mark.parametrize(("b", "off"), [(0.3, 4), (0.5, -7), (0.2j, 3)])
@pytest.mark.parametrize("floor", [0.0, 0.015])
def test_odd_share_against_the_analytic_reflection(b, off, floor):
    """An asymmetric residual (a second path ``off`` lags away): ``_odd_eps`` equals its
    docstring's formula with the reflection read in closed form, within the windowed-sinc
    interpolation's error (1e-5 absolute; measured 1.6e-6 at worst; the noise share's
    half at floor 0.015 is 6.5e-4 to 1.7e-3)."""

    def c_at(t):
        return ALPHA * R_an(t - J - D) + b * ALPHA * R_an(t - J - D - off)

    got = T._odd_eps(c_at(L), J, D, _wf(), floor)
    want = _odd_reference(c_at, J, D, floor)
    assert want > 1.5e-3 or floor > 0  # measured >= 3.0e-3 without noise
    assert got == pytest.approx(want, abs=1e-5)


def test_an_even_residual_has_no_odd_share():
    """Two paths placed symmetrically about the first, ``b`` real: the residual is even
    about ``tau`` (``alpha`` stays real): no odd share (below 1e-5:
    the interpolation's error), while one of them alone is odd."""
    wf = _wf()
    al = 0.8

    def c_at(t):
        return al * R_an(t - J - D) + 0.3 * al * (R_an(t - J - D - 5) + R_an(t - J - D + 5))

    assert T._odd_eps(c_at(L), J, D, wf, 0.0) < 1e-5  # measured 4.2e-6
    c = al * R_an(L - J - D) + 0.3 * al * R_an(L - J - D - 5)
    assert T._odd_eps(c, J, D, wf, 0.0) > 1e-3


def test_odd_share_window_needs_the_interpolations_pad():
    """``_odd_eps`` reads ``K + SINC_HALF + 2`` lags each side: 0 one sample short."""
    wf = _wf()
    h = K + T.SINC_HALF + 2
    c = _path(ALPHA, J + D) + _path(0.4 * ALPHA, J + D + 5)
    assert T._odd_eps(c[J - h :], h, D, wf, 0.0) > 1e-3
    assert T._odd_eps(c[J - h + 1 :], h - 1, D, wf, 0.0) == 0.0


# --- CLEAN steps (_other_paths) -----------------------------------------------------------


def _c_with(paths, d=D):
    c = _path(ALPHA, J + d)
    for a, p in paths:
        c = c + _path(a, p)
    return c


def test_other_paths_are_found_at_their_lags_with_their_amplitudes():
    """Two other paths at integer lags, 60 and 140 lags away (beyond two main lobes):
    ``(amplitude, lag)`` each, strongest first, to 1e-9."""
    want = [(0.5 - 0.2j, J + 140), (-0.3j, J - 60)]
    got = T._other_paths(_c_with(want), J, D, _wf(), 0.01)
    assert [p for _, p in got] == [J + 140, J - 60]
    for (a, _), (b, _) in zip(got, want, strict=True):
        assert a == pytest.approx(b, abs=1e-9)


def test_other_paths_stop_below_the_threshold_and_after_leak_paths():
    """Only paths at least ``thr``; at most LEAK_PATHS (8) of ten, the strongest."""
    wf = _wf()
    paths = [(0.5, J + 60), (0.2, J - 60)]
    assert [p for _, p in T._other_paths(_c_with(paths), J, D, wf, 0.3)] == [J + 60]
    assert [p for _, p in T._other_paths(_c_with(paths), J, D, wf, 0.19)] == [J + 60, J - 60]
    ten = [(0.1 * (10 - i), J + 40 * (i - 5) + (20 if i >= 5 else 0)) for i in range(10)]
    got = T._other_paths(_c_with(ten), J, D, wf, 0.01)
    assert T.LEAK_PATHS == 8 and len(got) == 8
    assert [p for _, p in got] == [p for _, p in ten[:8]]


@pytest.mark.parametrize("side", [1, -1])
def test_other_paths_within_the_self_responses_reach(side):
    """The window is the lags ``|l - j| < M`` (and inside ``c``): a path ``M - 1`` lags away
    is found at its lag; one ``M`` away is not located there (what reaches into the
    window is its side: found one lag nearer, if at all)."""
    wf = _wf()
    p_in = J + side * (M - 1)
    got = T._other_paths(_c_with([(0.5, p_in)]), J, 0.0, wf, 0.01)
    assert [p for _, p in got] == [p_in]
    p_out = J + side * M
    got = T._other_paths(_c_with([(0.5, p_out)]), J, 0.0, wf, 0.01)
    assert p_out not in [p for _, p in got]
    assert all(abs(p - J) < M for _, p in got)


@pytest.mark.parametrize("side", [1, -1])
def test_other_paths_are_sought_beyond_two_main_lobes(side):
    """The path's own lobes (``|l - j| <= 2 K``) are not searched: a path 2 K + 1 lags away
    is found at its lag, one at 2 K is not."""
    wf = _wf()
    p = J + side * (2 * K + 1)
    got = T._other_paths(_c_with([(0.6, p)], d=0.0), J, 0.0, wf, 0.01)
    assert got and got[0][1] == p
    p = J + side * 2 * K
    got = T._other_paths(_c_with([(0.6, p)], d=0.0), J, 0.0, wf, 0.01)
    assert p not in [q for _, q in got]


def test_other_paths_guards():
    """None without a window of ``4 K + 3`` lags, or with no path at ``j``."""
    wf = _wf()
    c = _c_with([(0.5, J + 60)])
    assert T._other_paths(c, J, D, wf, 0.01)
    c0 = c.copy()
    c0[J] = 0.0
    assert T._other_paths(c0, J, D, wf, 0.01) == []
    # A short c: the window [1, len - 1) must hold 4 K + 3 lags (= 2 * 2K + 3).
    short = _path(ALPHA, 20 + D, np.arange(41.0))
    short[1] += 0.5  # 19 lags before j = 20: beyond two lobes, inside the window
    got = T._other_paths(short, 20, D, wf, 0.01)
    assert [p for _, p in got] == [1]  # a window of 39 lags: searched
    assert T._other_paths(short[:40], 20, D, wf, 0.01) == []  # 38 lags: too short


# --- the side lobes' pull (_leakage) ------------------------------------------------------


def _true_shift(paths, d=D):
    t = np.linspace(J + d - 1.0, J + d + 1.0, 200001)
    ct = ALPHA * R_an(t - J - d)
    for a, p in paths:
        ct = ct + a * R_an(t - p)
    return float(t[np.argmax(np.abs(ct))] - (J + d))


@pytest.mark.parametrize("a", [0.3, 0.5, -0.4j])
@pytest.mark.parametrize("off", [15, 20, -15, -20, 25])
def test_the_pull_is_the_envelope_peaks_first_order_shift(a, off):
    """One other path ``a`` at ``j + off``: ``_leakage`` (signed, samples) against the
    exact shift of ``|c|``'s peak (a fine grid on the closed form): the ratio within
    0.7-1.5 (measured 0.84-1.33: the first order and the three-lag derivative)."""
    paths = [(complex(a), J + off)]
    pull = T._leakage(_c_with(paths), J, D, _wf(), paths)
    true = _true_shift(paths)
    assert abs(true) > 5e-6
    assert 0.7 < pull / true < 1.5, (pull, true)


def test_the_pull_guards():
    """0 without paths, at ``j`` 0 or the last sample, a path more than M lags away pulls
    nothing, and a flat self response (no curvature) gives 0."""
    wf = _wf()
    paths = [(0.5 + 0j, J + 15)]
    c = _c_with(paths)
    assert T._leakage(c, J, D, wf, []) == 0.0
    assert T._leakage(c, 0, D, wf, paths) == 0.0
    assert T._leakage(c, N_C - 1, D, wf, paths) == 0.0
    for j in (1, N_C - 2):
        edge = [(0.5 + 0j, j + 15 if j == 1 else j - 15)]
        cj = _path(ALPHA, j + D) + _path(0.5, edge[0][1])
        assert T._leakage(cj, j, D, wf, edge) != 0.0
    # A self response with tails to its ends (a small tone added): a path read at lags
    # |t - p| < M only, so one M + 1 lags from j (M from j + 1) pulls nothing.
    lag = np.arange(-M, M + 1.0)
    tailed = T._Filter(None, None, R_an(lag) + 0.01 * np.exp(2j * np.pi * F0 * lag), 0.03, 0.0,
                       K, np.ones(8) / 8, 0, 0.0, F0)  # fmt: skip
    for p, moved in ((J + M + 1, False), (J - M - 1, False), (J + M, True), (J - M, True)):
        assert bool(T._leakage(c, J, D, tailed, [(0.5 + 0j, p)]) != 0.0) is moved, p
    c0 = c.copy()
    c0[J] = 0.0
    assert T._leakage(c0, J, D, wf, paths) == 0.0
    flat = T._Filter(None, None, np.ones(2 * M + 1, complex), 0.03, 0.0, K, np.ones(8) / 8, 0,
                     0.0, F0)  # fmt: skip
    assert T._leakage(c, J, 0.0, flat, paths) == 0.0


# --- the shape term with the other paths taken out (_unexplained) ------------------------


def test_unexplained_once_the_other_paths_are_subtracted():
    """Two other paths whose lobes reach into the window ``j +- 2 K`` (at +20 and -18):
    subtracted, nothing is left (below 1e-12); not subtracted, ``_shape``'s share of ``c``;
    and it is ``_shape`` of ``c`` less the paths (computed here)."""
    wf = _wf()
    paths = [(0.4 + 0.1j, J + 20), (-0.3 + 0j, J - 18)]
    c = _c_with(paths)
    assert T._unexplained(c, J, D, wf, 0.0, paths) < 1e-12
    alone = T._unexplained(c, J, D, wf, 0.0, [])
    assert (
        alone == pytest.approx(T._shape(c, J, D, wf, 0.0)[0], rel=1e-12) and alone > 1e-3
    )  # measured 1.8e-3
    half = _c_with(paths[1:])
    got = T._unexplained(c, J, D, wf, 0.002, paths[:1])
    assert got == pytest.approx(_eps_reference(half, J, D, 0.002), rel=1e-9, abs=1e-14)
    h = 2 * K
    assert T._unexplained(c[J - h :], h, D, wf, 0.0, []) > 0.0
    assert T._unexplained(c[J - h + 1 :], h - 1, D, wf, 0.0, []) == 0.0
    assert T._unexplained(c[: J + h + 1], J, D, wf, 0.0, []) > 0.0
    assert T._unexplained(c[: J + h], J, D, wf, 0.0, []) == 0.0


# --- a tail's decay line (_decay, _tail_level) ------------------------------------------


def _exp_env(a_db: float, b_db: float, n: int = 3000) -> np.ndarray:
    return 10.0 ** ((a_db + b_db * np.arange(float(n))) / 20.0)


@pytest.mark.parametrize(("look", "sep"), [(100, 900), (0, 801), (37, 837)])
def test_decay_of_an_exponential_tail_is_its_own_line(look, sep):
    """An envelope decaying exactly exponentially, ``20 log10 env = A + B t``: the maxima
    of 8 blocks of ``[q + max(look, 1), q + sep)`` (800 samples: blocks of 100, each at its
    first sample) lie on ``A + B (t - 50)`` at the blocks' centres ``t``, so the line is
    ``(A - 50 B, B, inf)`` (no raise needed)."""
    A, B = 10.0, -0.02
    a, b, t_end = T._decay(_exp_env(A, B), 500, sep, look)
    assert b == pytest.approx(B, rel=1e-9)
    assert a == pytest.approx(A - 50.0 * B, abs=1e-8)
    assert t_end == math.inf


def test_decay_is_raised_over_every_block_maximum():
    """An echo on the tail: the line keeps the fitted slope and passes over every block's
    maximum, touching the highest above it."""
    env = _exp_env(0.0, -0.02)
    env[850:860] += 0.5  # an echo in the fourth block of [600, 1400)
    a, b, _ = T._decay(env, 500, 900, 100)
    edges = np.linspace(600, 1400, 9).astype(int)
    t = 0.5 * (edges[:-1] + edges[1:])
    y = 20.0 * np.log10([env[u:v].max() for u, v in itertools.pairwise(edges)])
    slope, _ = np.polyfit(t, y, 1)
    assert b == pytest.approx(slope, rel=1e-9)
    gap = a + b * t - y
    assert gap.min() == pytest.approx(0.0, abs=1e-9) and gap.min() >= -1e-9
    assert int(np.argmin(gap)) == 2  # the echo's block (850-860 lies in [800, 900))


def test_decay_of_a_rising_tail_is_flat_at_its_maximum_up_to_the_stretch_end():
    """Echoes late in the stretch (the block maxima rise): ``(max, 0, hi)``, ``hi`` the
    stretch's end, clipped to the envelope."""
    env = _exp_env(-20.0, 0.01)
    y_max = 20.0 * np.log10(env[500 + 100 : 500 + 900].max())
    assert T._decay(env, 500, 900, 100) == pytest.approx((y_max, 0.0, 1400.0))
    assert T._decay(env[:1200], 500, 900, 100)[2] == 1200.0


def test_decay_needs_64_samples_and_a_tail_in_every_block():
    """None when the stretch is shorter than 64 samples or a block is all zeros."""
    env = _exp_env(0.0, -0.02)
    assert T._decay(env, 500, 164, 100) is not None
    assert T._decay(env, 500, 163, 100) is None
    assert T._decay(env[:663], 500, 900, 100) is None  # the envelope ends: 63 samples
    assert T._decay(env[:664], 500, 900, 100) is not None
    z = env.copy()
    z[1300:1400] = 0.0  # the last block of [600, 1400)
    assert T._decay(z, 500, 900, 100) is None


def test_tail_level_is_the_line_in_amplitude_up_to_its_end():
    """``10^((a + b p) / 20)`` up to ``t_end`` (inclusive), 0 beyond or without a line."""
    assert T._tail_level(None, 10) == 0.0
    assert T._tail_level((6.0, -0.5, 100.0), 20) == pytest.approx(10.0 ** (-4.0 / 20.0))
    assert T._tail_level((6.0, -0.5, 100.0), 100) == pytest.approx(10.0 ** (-44.0 / 20.0))
    assert T._tail_level((6.0, -0.5, 100.0), 101) == 0.0
    assert T._tail_level((6.0, 0.0, math.inf), 10**6) == pytest.approx(10.0**0.3)


# --- the cluster and its local floor (_cluster_start, _local_floor, _local_maxima) -------


def _peaks_env(at, height=1.0, n=1200):
    env = np.zeros(n)
    env[list(at)] = height
    return env


@pytest.mark.parametrize(
    ("look", "cap", "want"),
    [(100, 600, 850), (149, 600, 850), (150, 600, 700), (150, 300, 700), (150, 299, 850)],
)
def test_cluster_start_chains_back_in_gaps_of_at_most_look(look, cap, want):
    """Peaks at 700, 850, 900 before ``p`` = 1000: chained back through gaps of at most
    ``look`` (a gap of exactly ``look`` joins), no further back than ``p - cap``
    (inclusive)."""
    at = [700, 850, 900, 1000]
    env = _peaks_env(at)
    assert T._cluster_start(env, np.array(at), 1000, 0.5, look, cap) == want


def test_cluster_start_thresholds_and_breaks():
    """A peak below ``thr`` is not a link (one at ``thr`` is); a gap above ``look`` just
    before ``p`` leaves ``p`` alone; ``look`` 0 is ``p``."""
    at = np.array([700, 850, 900, 1000])
    env = _peaks_env(at)
    env[850] = 0.4
    assert T._cluster_start(env, at, 1000, 0.5, 150, 600) == 900
    assert T._cluster_start(env, at, 1000, 0.4, 150, 600) == 700
    assert T._cluster_start(env, at, 1000, 0.5, 99, 600) == 1000
    assert T._cluster_start(env, at, 1000, 0.5, 100, 600) == 900
    assert T._cluster_start(env, at, 1000, 0.5, 0, 600) == 1000
    assert T._cluster_start(env, at, 1000, 2.0, 150, 600) == 1000  # none above thr


RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))


@pytest.mark.parametrize(
    ("start", "look", "half_lobe", "n"),
    [
        (9000, 100, 5, 256),  # max(2 look, 32 half lobes, 256) = 256
        (9000, 300, 5, 600),
        (9000, 100, 20, 640),
        (9000, 3000, 5, 4096),  # at most 4096
        (9000, 2047, 5, 4094),
        (700, 300, 5, 600),
        (300, 300, 5, 289),  # from sample 0
    ],
)
def test_local_floor_is_the_rayleigh_scale_of_the_stretch_a_lobe_before(start, look, half_lobe, n):
    """On ``env = 1, 2, 3, ...`` the median of ``env[lo:end]`` is ``(lo + end + 1) / 2``:
    the window ends ``2 half_lobe + 1`` before ``start`` and is ``n`` long (or reaches
    sample 0); the Rayleigh scale is the median over ``sqrt(2 ln 2)``."""
    env = np.arange(1.0, 10001.0)
    end = start - 2 * half_lobe - 1
    lo = end - n
    assert lo >= 0
    want = 0.5 * (lo + end + 1) / RAYLEIGH_MEDIAN
    assert T._local_floor(env, start, look, half_lobe) == pytest.approx(want, rel=1e-12)


def test_local_floor_needs_16_samples():
    """0 when the window before the cluster holds fewer than 16 samples."""
    env = np.arange(1.0, 10001.0)
    start = 2 * 5 + 1 + 16  # end = 16: the window [0, 16)
    assert T._local_floor(env, start, 100, 5) == pytest.approx(8.5 / RAYLEIGH_MEDIAN)
    assert T._local_floor(env, start - 1, 100, 5) == 0.0


def test_local_maxima_against_a_loop():
    """``>=`` the left neighbour and ``>`` the right one, interior samples only: on a
    plateau the last sample; on random integers (ties) as a loop finds them."""
    np.testing.assert_array_equal(T._local_maxima(np.array([1.0, 2.0, 2.0, 1.0])), [2])
    np.testing.assert_array_equal(T._local_maxima(np.array([3.0, 1.0, 3.0])), [])
    assert len(T._local_maxima(np.array([1.0, 2.0]))) == 0
    rng = np.random.default_rng(4)
    x = rng.integers(0, 4, 500).astype(float)
    want = [i for i in range(1, 499) if x[i] >= x[i - 1] and x[i] > x[i + 1]]
    np.testing.assert_array_equal(T._local_maxima(x), want)


# --- the filter: template PSD, bandwidth, shares, half lobe, reach (_base, _weighted) ----


def _probe(f0, f1, dur, fs=FS, band=None):
    p = linear_sweep(f0, f1, dur, fs=fs)
    if band is not None:  # a chosen band (what band_hz() returns), e.g. on FFT bins
        p.__dict__["_band"] = band
    return p


@pytest.mark.parametrize(
    ("fs", "nperseg"), [(44100.0, 1024), (8000.0, 256), (2000.0, 64), (1000.0, 64), (96000.0, 2048)]
)
def test_noise_segment_is_a_power_of_two_near_fs_over_40_hz(fs, nperseg):
    """``nperseg = 2^max(6, round(log2(fs / 40 Hz)))`` (about 40 Hz resolution, at least
    64), and the template's PSD is scipy's Welch estimate with it (Hann, half overlap, the
    segment cut to the template)."""
    p = _probe(0.05 * fs, 0.3 * fs, 0.05, fs=fs)
    base = T._base(p, fs, DEFAULT_BLOCK)
    assert base.nperseg == nperseg
    h = p.at_rate(fs)
    nper = min(nperseg, len(h))
    _, S2 = welch(h, fs=fs, nperseg=nper, nfft=nperseg, window="hann", noverlap=nper // 2)
    np.testing.assert_allclose(base.template_psd, S2, rtol=1e-12, atol=1e-300)
    assert base.band_fs == 0.5 * fs
    np.testing.assert_array_equal(base.template, h)


def test_a_short_templates_psd_uses_a_segment_its_length():
    """A 10 ms template at 48 kHz (480 samples, under the 1024 of nperseg)."""
    fs = 48000.0
    p = _probe(2000.0, 8000.0, 0.01, fs=fs)
    base = T._base(p, fs, DEFAULT_BLOCK)
    h = p.at_rate(fs)
    assert len(h) == 480 and base.nperseg == 1024
    _, S2 = welch(h, fs=fs, nperseg=480, nfft=1024, window="hann", noverlap=240)
    np.testing.assert_allclose(base.template_psd, S2, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize(
    ("band", "taps_band"),
    [
        ((500.0, 20000.0), (500.0, 20000.0)),  # from 500 Hz: band-passed
        ((499.0, 20000.0), None),  # below, and high enough: no FIR
        ((100.0, 19844.0), (0.0, 19844.0)),  # below 0.9 Nyquist: low-passed
        ((100.0, 0.9 * 22050.0), None),
        ((600.0, 21900.0), (600.0, 0.98 * 22050.0)),  # the top at most 0.98 Nyquist
    ],
)
def test_band_limiting_fir_by_the_probes_band(band, taps_band):
    """Band-passed from :data:`_MIN_HIGHPASS_HZ` (500 Hz) up, low-passed when the band ends
    below 0.9 of the Nyquist frequency, nothing otherwise; the band's top is clipped at
    0.98 of it."""
    from rangekit.detect.condition import bandpass_taps

    p = _probe(1000.0, 15000.0, 0.05, band=band)
    base = T._base(p, FS, DEFAULT_BLOCK)
    assert base.band == (band[0], min(band[1], 0.98 * 22050.0))
    if taps_band is None:
        assert base.bp_taps is None
    else:
        np.testing.assert_array_equal(base.bp_taps, bandpass_taps(FS, *taps_band))


def _reference_filter_terms(p, fs, taps):
    """fc, beta (cycles per sample) and the 8 sub-band shares of ``|S|^2 |H|``: scipy's
    Welch PSD of the template times the FIR's zero-phase response in closed form."""
    base = T._base(p, fs, DEFAULT_BLOCK)
    h = p.at_rate(fs)
    nperseg = base.nperseg
    nper = min(nperseg, len(h))
    _, S2 = welch(h, fs=fs, nperseg=nper, nfft=nperseg, window="hann", noverlap=nper // 2)
    f = np.fft.rfftfreq(nperseg)
    if taps is not None:
        k = np.arange(len(taps)) - (len(taps) - 1) // 2
        S2 = S2 * np.abs(np.cos(2 * np.pi * np.outer(f, k)) @ taps)
    fc = float(f @ S2 / S2.sum())
    beta = math.sqrt(float(((f - fc) ** 2) @ S2 / S2.sum()))
    lo, hi = base.band
    edges = lo + (min(hi, 0.5 * fs) - lo) * np.arange(9) / 8.0
    fh = f * fs
    sh = np.array([S2[(fh >= a) & (fh < b)].sum() for a, b in itertools.pairwise(edges)])
    return fc, beta, sh / sh.sum()


def _reference_interp_rms(sr):
    m = len(sr) // 2
    f = np.fft.fftfreq(len(sr))
    errs = []
    for k in range(16):
        e = np.abs(np.fft.ifft(np.fft.fft(sr) * np.exp(-2j * np.pi * f * k / 16)))
        i = int(np.argmax(e))
        errs.append(i + interp_peak(e, i)[0] - (m + k / 16))
    return float(np.sqrt(np.mean(np.square(errs))))


PROBES = [(17000.0, 20000.0, 0.1), (20.0, 20000.0, 0.05), (2000.0, 6000.0, 0.02)]


@pytest.mark.parametrize(("f0", "f1", "dur"), PROBES)
def test_unweighted_filter_against_its_definitions(f0, f1, dur):
    """The plain filter: its self response the matched filter's cut to ``+- (look +
    256)``; RMS bandwidth and frequency, sub-band shares, interpolation RMS, half lobe
    (the first lag where ``|R|`` falls to a quarter, at least 2), coherent reach (a
    quarter carrier period and a sample where the real self response has no rival
    cycle), each from its definition."""
    from rangekit.detect._coherent import coherent_interp_rms, real_side_ratio

    p = _probe(f0, f1, dur)
    look = 300
    wf = T._unweighted(p, FS, DEFAULT_BLOCK, look)
    assert wf.taps is None and wf.reach == 0
    sr = T._base(p, FS, DEFAULT_BLOCK).mf.self_response
    mid, w = len(sr) // 2, look + 256
    np.testing.assert_array_equal(wf.self_resp, sr[mid - w : mid + w + 1])
    fc, beta, shares = _reference_filter_terms(p, FS, None)
    assert wf.beta == pytest.approx(beta, rel=1e-9)
    assert wf.f_rms == pytest.approx(math.hypot(fc, beta), rel=1e-9)
    np.testing.assert_allclose(wf.shares, shares, rtol=1e-9, atol=1e-15)
    assert wf.interp_rms == pytest.approx(max(_reference_interp_rms(wf.self_resp), 1e-6), rel=1e-9)
    env = np.abs(wf.self_resp[w:])
    k = int(np.flatnonzero(env <= 0.25 * env[0])[0])
    assert wf.half_lobe == max(2, k)
    wide = real_side_ratio(wf.self_resp, max(2 * wf.half_lobe, 8)) <= 0.5
    assert wide is (f0 < 100.0)  # only the 20 Hz-20 kHz sweep is timed coherently
    if wide:
        assert wf.coherent_reach == math.ceil(0.25 / fc) + 1
        assert wf.coherent_rms == coherent_interp_rms(wf.self_resp, wf.coherent_reach)
    else:
        assert wf.coherent_reach == 0 and wf.coherent_rms == 0.0


def test_self_response_is_zero_padded_beyond_the_filters_own():
    """A 20 ms template's self response is 3841 lags; cut to ``+- (2000 + 256)`` it is
    zero beyond its own ``+- 1920``."""
    p = _probe(2000.0, 6000.0, 0.02)
    sr = T._base(p, FS, DEFAULT_BLOCK).mf.self_response
    mid = len(sr) // 2
    wf = T._unweighted(p, FS, DEFAULT_BLOCK, 2000)
    w = 2256
    assert len(wf.self_resp) == 2 * w + 1 and mid < w
    np.testing.assert_array_equal(wf.self_resp[w - mid : w + mid + 1], sr)
    assert not np.any(wf.self_resp[: w - mid]) and not np.any(wf.self_resp[w + mid + 1 :])


def test_shares_count_each_bin_in_one_half_open_sub_band():
    """A band on FFT bins (3-9 kHz at 48 kHz, bins of 46.875 Hz: sub-band edges every 16
    bins): each bin in ``[lo, hi)`` of one sub-band, the band's top bin in none; the shares
    sum to 1."""
    fs = 48000.0
    p = _probe(2000.0, 10000.0, 0.05, fs=fs, band=(3000.0, 9000.0))
    wf = T._unweighted(p, fs, DEFAULT_BLOCK, 300)
    base = T._base(p, fs, DEFAULT_BLOCK)
    S2 = base.template_psd
    sh = np.array([S2[64 + 16 * b : 64 + 16 * (b + 1)].sum() for b in range(8)])
    np.testing.assert_allclose(wf.shares, sh / sh.sum(), rtol=1e-12)
    assert wf.shares.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(T._subband_edges(base.band, fs), 3000.0 + 750.0 * np.arange(9))
    # the band clipped at the Nyquist frequency
    np.testing.assert_allclose(T._subband_edges((3000.0, 30000.0), fs), np.linspace(3000, 24000, 9))


def _coloured_spectra(p, seed=0):
    """Noise rising 40 dB towards low frequencies, as a recording's spectrum."""
    base = T._base(p, FS, DEFAULT_BLOCK)
    x = np.random.default_rng(seed).standard_normal(40000)
    x = x + 30.0 * np.cumsum(np.random.default_rng(seed + 1).standard_normal(40000)) * 1e-2
    return base, welch_spectra(x, fs=FS, nperseg=base.nperseg)


@pytest.mark.parametrize(("f0", "f1", "dur"), PROBES)
def test_weighted_filter_bandwidth_and_shares_through_the_fir(f0, f1, dur):
    """Weighted by coloured noise ("ml"): the FIR is the band-limiting one convolved with
    the weights' zero-phase FIR; the RMS bandwidth and shares are those of ``|S|^2`` times
    the FIR's response in closed form (``sum taps cos(2 pi f (k - reach))``) on the
    weights' grid."""
    from rangekit.detect.matched import zero_phase_taps

    p = _probe(f0, f1, dur)
    base, sp = _coloured_spectra(p)
    W = weighting_response("ml", sp, template_psd=base.template_psd, band_hz=base.band)
    wf = T._weighted(p, FS, DEFAULT_BLOCK, W, 300)
    taps = zero_phase_taps(W, 2 * (len(W) - 1))
    if base.bp_taps is not None:
        taps = np.convolve(base.bp_taps, taps)
    np.testing.assert_array_equal(wf.taps, taps)
    assert wf.reach == (len(taps) - 1) // 2
    fc, beta, shares = _reference_filter_terms(p, FS, taps)
    assert wf.beta == pytest.approx(beta, rel=1e-9)
    assert wf.f_rms == pytest.approx(math.hypot(fc, beta), rel=1e-9)
    np.testing.assert_allclose(wf.shares, shares, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("n", [4096, 600, 61])
def test_taps_response_is_the_zero_phase_cosine_sum(n):
    """``_taps_response`` on ``rfftfreq(n)``: ``sum taps[k] cos(2 pi f (k - reach))``, for
    ``n`` above and below the FIR's length (then read off a finer grid); 1 without FIR."""
    rng = np.random.default_rng(7)
    half = rng.standard_normal(150)
    taps = np.concatenate([half[::-1], [2.0], half])  # even: zero phase about its middle
    wf = T._Filter(None, taps, np.ones(3, complex), 0.1, 0.0, 2, np.ones(8) / 8, 0, 0.0, 0.1)
    f = np.fft.rfftfreq(n)
    k = np.arange(len(taps)) - 150
    want = np.cos(2 * np.pi * np.outer(f, k)) @ taps
    np.testing.assert_allclose(T._taps_response(wf, n), want, atol=1e-9)
    none = T._Filter(None, None, np.ones(3, complex), 0.1, 0.0, 2, np.ones(8) / 8, 0, 0.0, 0.1)
    np.testing.assert_array_equal(T._taps_response(none, n), np.ones(n // 2 + 1))


def test_template_spectrum_and_shifted():
    """The template's rfft (cached), and ``_shifted``: an integer delay is a roll, a
    fractional one a band-limited tone's delay (to 1e-12)."""
    p = _probe(17000.0, 20000.0, 0.1)
    base = T._base(p, FS, DEFAULT_BLOCK)
    np.testing.assert_allclose(T._template_spectrum(base), np.fft.rfft(base.template), atol=1e-9)
    assert T._template_spectrum(base) is T._template_spectrum(base)
    rng = np.random.default_rng(2)
    r = rng.standard_normal(64) + 1j * rng.standard_normal(64)
    np.testing.assert_allclose(T._shifted(r, 3.0), np.roll(r, 3), atol=1e-12)
    np.testing.assert_allclose(T._shifted(r, -5.0), np.roll(r, -5), atol=1e-12)
    n = np.arange(64.0)
    tone = np.exp(2j * np.pi * 5 / 64 * n)
    np.testing.assert_allclose(T._shifted(tone, 0.3), np.exp(2j * np.pi * 5 / 64 * (n - 0.3)),
                               atol=1e-12)  # fmt: skip


# --- whole detections: sigma's terms, the transducer term, SNR, confidence, low_snr -------


def _recording(p, onsets, amps, noise, seed, n=20000):
    from probecorpus import place

    x = place(p.samples, onsets, amps, n)
    return x + noise * np.random.default_rng(seed).standard_normal(n)


def _ripple_6db(beta):
    """The transducer term of +-6 dB of ripple: ``A / (2 pi beta)``, ``A = 6 ln 10 / 20``
    nepers (``transducer_sigma``'s docstring)."""
    return 6.0 * math.log(10.0) / 20.0 / (2.0 * math.pi * beta)


def _filter_of(p, x, look):
    base = T._base(p, FS, DEFAULT_BLOCK)
    sp = welch_spectra(x, fs=FS, nperseg=base.nperseg)
    W = weighting_response("ml", sp, template_psd=base.template_psd, band_hz=base.band)
    return T._weighted(p, FS, DEFAULT_BLOCK, W, look)


@pytest.mark.parametrize("onset", [3000.0, 3000.37])
@pytest.mark.parametrize("seed", [0, 2, 3])
def test_sigma_of_a_clean_narrow_arrival_is_its_crb_and_interpolation_terms(onset, seed):
    """A 2-6 kHz sweep (20 ms: lookback 441 samples, half the separation) in white noise,
    flat transducers: nothing unexplained beyond the noise share, no other path, so
    ``sigma = sqrt(s_crb^2 + s_interp^2)`` with ``s_crb = 1 / (2 pi beta_w snr)`` (snr from
    the reported ``snr_db``), to 1e-9 (measured 1e-15; so in 7 of seeds 0-7: in seed 1's
    draw the noise leaves more than its share unexplained, and the shape term adds 23 %,
    tested below as a lower bound). With +-6 dB of ripple sigma adds
    ``transducer_sigma(beta_w)`` in quadrature, which ``sigma_transducer`` reports."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [onset], [1.0], 1e-3, seed)
    a0 = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)
    a6 = T.detect_template(x, fs=FS, probe=p)
    assert len(a0) == 1 and abs(a0.onset[0] - onset) < 3.0 * a0.sigma[0]  # measured 0.9 sigma
    wf = _filter_of(p, x, 441)
    snr = 10.0 ** (a0.snr_db[0] / 20.0)
    want = math.hypot(1.0 / (2.0 * math.pi * wf.beta * snr), wf.interp_rms)
    assert a0.sigma[0] == pytest.approx(want, rel=1e-9)
    assert a0.sigma_transducer[0] == 0.0
    s_td = _ripple_6db(wf.beta)
    assert a6.sigma_transducer[0] == pytest.approx(s_td, rel=1e-9)
    assert a6.sigma[0] == pytest.approx(math.hypot(a0.sigma[0], s_td), rel=1e-9)
    np.testing.assert_array_equal(a6.onset, a0.onset)
    np.testing.assert_array_equal(a6.burst_onsets[:, 0], a6.onset)
    assert a6.detector == "template" and a6.flags[0] == 0 and a6.confidence[0] == 1.0


def test_sigma_is_at_least_the_crb_and_interpolation_terms():
    """Seed 1 (the shape term 0.23x up) and a noiseless arrival at an integer lag (the
    SNR capped at 120 dB: sigma is the interpolation term, equal to 1e-8)."""
    p = _probe(2000.0, 6000.0, 0.02)
    for noise, seed in ((1e-3, 1), (0.0, 0)):
        x = _recording(p, [3000.0], [1.0], noise, seed)
        a = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)
        wf = _filter_of(p, x, 441)
        snr = 10.0 ** (a.snr_db[0] / 20.0)
        low = math.hypot(1.0 / (2.0 * math.pi * wf.beta * snr), wf.interp_rms)
        assert low * (1 - 1e-9) <= a.sigma[0] <= 1.5 * low  # measured 1.23x and 1.0x
    assert a.sigma[0] == pytest.approx(low, rel=1e-8)


def test_sigma_of_a_clean_wide_arrival_is_its_coherent_terms():
    """A 20 Hz-20 kHz sweep at an integer lag, in phase (weight 1): ``sigma =
    sqrt(s_coh^2 + coherent_rms^2)``, ``s_coh = 1 / (2 pi F_w snr)`` (measured equal to
    1e-9), and the transducer term ``transducer_sigma(F_w)``."""
    p = _probe(20.0, 20000.0, 0.1)
    x = _recording(p, [3000.0], [1.0], 1e-3, 0)
    a0 = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)
    a6 = T.detect_template(x, fs=FS, probe=p)
    wf = _filter_of(p, x, 882)
    assert wf.coherent_reach > 0
    snr = 10.0 ** (a0.snr_db[0] / 20.0)
    want = math.hypot(1.0 / (2.0 * math.pi * wf.f_rms * snr), wf.coherent_rms)
    assert a0.sigma[0] == pytest.approx(want, rel=1e-4)
    assert a6.sigma_transducer[0] == pytest.approx(_ripple_6db(wf.f_rms), rel=1e-9)
    assert a6.sigma[0] == pytest.approx(math.hypot(a0.sigma[0], a6.sigma_transducer[0]), rel=1e-9)


def test_snr_of_a_noiseless_arrival_is_capped_by_the_noise_floor():
    """Without noise the level is the median of the envelope's non-silent samples (the
    filter's own tails: 89.7 dB under the peak, measured; 120 dB, NOISE_FLOOR_REL, until
    digital silence was left out, 2026-12-04), never under NOISE_FLOOR_REL (1e-6) of the
    peak: the SNR stays at most 120 dB."""
    p = _probe(2000.0, 6000.0, 0.02)
    a = T.detect_template(_recording(p, [3000.0], [1.0], 0.0, 0), fs=FS, probe=p)
    assert a.snr_db[0] == pytest.approx(89.7, abs=0.5)
    assert a.flag_names(0) == ()
    # the floor: an envelope whose live median lies under 1e-6 of its peak
    env = np.zeros(1000)
    env[500] = 1.0
    env[1::2] += 1e-9
    noise = max(T.noise_level(T._not_silent(env)), T.NOISE_FLOOR_REL * float(env.max()))
    assert noise == T.NOISE_FLOOR_REL


def test_confidence_is_the_first_paths_height_over_the_strongest():
    """A direct path at half a reflection's amplitude, 3 ms before it: the onset is the
    direct path's, confidence about 0.5 (the heights' ratio, measured 0.50)."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.0, 3000.0 + 0.003 * FS], [0.5, 1.0], 1e-3, 0)
    a = T.detect_template(x, fs=FS, probe=p)
    assert len(a) == 1 and abs(a.onset[0] - 3000.0) < 0.015  # measured 0.0076
    assert a.confidence[0] == pytest.approx(0.5, abs=0.01)  # measured 0.4975


@pytest.mark.parametrize("k_detect", [4.5, 8.0])
def test_low_snr_at_either_side_of_twice_the_detection_threshold(k_detect):
    """``low_snr``: the first path's SNR below LOW_SNR_FACTOR (2) times ``k_rec = max(k_detect,
    sqrt(2 ln(n / FALSE_ALARM)))`` (n = 20000: 5.80, so 21.3 dB; with ``k_detect`` 8, 24.1
    dB). Amplitudes set to put the SNR 0.1 dB either side (the SNR scales with the
    amplitude in fixed noise)."""
    p = _probe(2000.0, 6000.0, 0.02)
    n = 20000
    k_rec = max(k_detect, math.sqrt(2.0 * math.log(n / 1e-3)))
    thr_db = 20.0 * math.log10(2.0 * k_rec)
    probe_amp = 1.5
    kw = {"k_detect": k_detect}
    a = T.detect_template(_recording(p, [3000.0], [probe_amp], 1.0, 3, n), fs=FS, probe=p, **kw)
    got = []
    for off in (-0.1, 0.1):
        amp = probe_amp * 10.0 ** ((thr_db + off - a.snr_db[0]) / 20.0)
        b = T.detect_template(_recording(p, [3000.0], [amp], 1.0, 3, n), fs=FS, probe=p, **kw)
        assert len(b) == 1 and abs(b.snr_db[0] - thr_db - off) < 0.05  # measured <= 0.03
        got.append(bool(b.flags[0] & 2))
    assert got == [True, False]


# --- the near-miss test (_near_miss) -------------------------------------------------------


def _R2(t):
    """A self response with a side lobe half as high 30 lags before its peak."""
    return R_an(t) + 0.5 * R_an(t + 30.0)


def _wf2() -> T._Filter:
    R = _R2(np.arange(-M, M + 1.0))
    return T._Filter(None, None, R, 0.03, 0.0, K, np.ones(8) / 8, 0, 0.0, F0)


def _near(c, lo, paths, thr, wf=None):
    return T._near_miss(c, np.abs(c), lo, paths, _wf2() if wf is None else wf, thr)


def test_the_paths_own_side_lobes_are_no_near_miss():
    """A side lobe 30 lags before the chosen path, at half its height, above ``thr /
    AMBIGUOUS_MARGIN``: subtracted with the path's response (at its sub-sample offset),
    nothing is left."""
    c = _R2(L - J - D)
    assert not _near(c, J - 100, [(J, D), (J, D)], 0.6)
    assert _near(c, J - 100, [(J, D), (J, D)], 0.6, wf=_wf())  # a filter without the lobe


@pytest.mark.parametrize(("factor", "want"), [(1.01, True), (0.99, False)])
def test_an_earlier_path_nearly_clearing_the_threshold(factor, want):
    """An earlier path (amplitude ``b``, 80 lags before) is a near miss when it reaches
    ``thr / AMBIGUOUS_MARGIN``: ``thr`` set 1 % either side of ``1.5 b``."""
    b = 0.2
    c = _R2(L - J - D) + _path(b, J - 80)
    thr = 1.5 * b / factor
    assert _near(c, J - 100, [(J, D), (J, D)], thr) is want


def test_near_miss_subtracts_the_strongest_path_too():
    """The chosen path and one twice as strong 15 lags later, each with its side lobe:
    both are subtracted, each at its own offset (the strongest's lobe lies 15 lags before
    the chosen path); with only the chosen path's response taken out the strongest's lobe
    is a near miss."""
    c = _R2(L - J - D) + 2.0 * _R2(L - J - 15 - 0.6)
    assert not _near(c, J - 100, [(J, D), (J + 15, 0.6)], 0.6)
    assert _near(c, J - 100, [(J, D), (J, D)], 0.6)


def test_near_miss_window():
    """The earlier peaks are sought in ``[max(lo, 1), j - half_lobe)``: none when that is
    under one sample, and an earlier peak below ``thr / 1.5`` is none (False, not a near
    miss); a path at sample 1 is looked at, one at sample 0 is not."""
    c = _R2(L - J - D)
    assert not _near(c, J - K, [(J, D), (J, D)], 0.6)
    assert not _near(c, J - K - 1, [(J, D), (J, D)], 0.6)
    assert not _near(c, J - 100, [(J, D), (J, D)], 10.0)  # nothing near the threshold
    for at, want in ((1, True), (0, False)):
        x = _R2(L - 150 - D) + _path(0.3, at)
        assert _near(x, 0, [(150, D), (150, D)], 0.3) is want, at


# --- arrivals from an envelope (_select) ---------------------------------------------------


def _sel(env, *, sep=900, look=100, k_rec=5.0, expected=None):
    wf = _wf(half_lobe=5)
    peaks = T._local_maxima(env)
    peaks = peaks[env[peaks] > k_rec * 0.85]
    return T._select(env, peaks, noise=0.85, k_rec=k_rec, k_noise=3.0, rel_threshold=0.3,
                     sep=sep, look=look, wf=wf, expected=expected)  # fmt: skip


def _spikes(at_heights, n=8000):
    env = np.full(n, 2.0)  # a flat background (no local maxima): Rayleigh scale 1.70
    for at, h in at_heights:
        env[at] = h
    return env


@pytest.mark.parametrize(("gap", "n_arrivals"), [(899, 1), (900, 2)])
def test_a_peak_within_the_separation_belongs_to_the_stronger(gap, n_arrivals):
    env = _spikes([(2000, 100.0), (2000 + gap, 50.0)])
    got = _sel(env)
    assert [p for p, _, _, _ in got] == [2000, 2000 + gap][:n_arrivals]
    assert all(not tail for *_, tail in got)


@pytest.mark.parametrize(("factor", "accepted"), [(1.01, True), (0.99, False)])
def test_an_arrival_clears_k_rec_times_its_local_floor(factor, accepted):
    """The local floor before a lone peak is the background's Rayleigh scale (``2 /
    sqrt(2 ln 2)``, above ``noise`` 0.85): the peak is an arrival from ``k_rec`` times it
    (1 % either side)."""
    floor = 2.0 / RAYLEIGH_MEDIAN
    env = _spikes([(3000, factor * 5.0 * floor)])
    got = _sel(env)
    if accepted:
        assert len(got) == 1 and got[0][0] == 3000 and got[0][1] == 3000
        assert got[0][2] == pytest.approx(floor, rel=1e-12) and not got[0][3]
    else:
        assert got == []
        assert _sel(env, expected=1) == [(3000, 3000, pytest.approx(floor), True)]


def test_expected_keeps_the_strongest_and_fills_with_tail_peaks():
    """Three arrivals and a peak below its floor: ``expected=2`` the two strongest,
    ``expected=4`` all four, the last flagged a tail (weakest of the tails first)."""
    floor = 2.0 / RAYLEIGH_MEDIAN
    env = _spikes([(1000, 50.0), (3000, 80.0), (5000, 30.0), (7000, 4.5 * floor)])
    assert [p for p, *_ in _sel(env)] == [3000, 1000, 5000]
    assert [p for p, *_ in _sel(env, expected=2)] == [3000, 1000]
    got = _sel(env, expected=4)
    assert [(p, tail) for p, _, _, tail in got] == [
        (3000, False), (1000, False), (5000, False), (7000, True)
    ]  # fmt: skip
    assert [p for p, *_ in _sel(env, expected=1)] == [3000]


def test_an_arrivals_cluster_reaches_back_in_gaps_of_at_most_look_within_half_sep():
    """A peak 950 samples after an arrival, preceded by a chain of peaks every 90 samples:
    its cluster starts at the earliest chained peak no more than ``sep / 2`` (450) back
    (2540) when ``look`` is 90, at the last gap's end (2900) when it is 89."""
    chain = [(2000 + 90 * i, 40.0) for i in range(1, 11)]  # every 90 samples to 2900
    env = _spikes([(2000, 100.0), *chain, (2950, 45.0)])
    for look, start in ((90, 2540), (89, 2900)):
        got = _sel(env, sep=900, look=look)
        assert [(p, s, tail) for p, s, _, tail in got] == [
            (2000, 2000, False),
            (2950, start, False),
        ]


@pytest.mark.parametrize(("factor", "accepted"), [(1.01, True), (0.99, False)])
def test_a_peak_under_an_arrivals_extrapolated_tail_is_its_echo(factor, accepted):
    """An arrival with an echo late in its stretch (``[q + look, q + sep)``: the tail's
    upper envelope is flat at the echo's height up to ``q + sep``): a peak at ``q + sep``
    is a new arrival only above TAIL_MARGIN (2) times that (1 % either side)."""
    echo = 10.0
    env = _spikes([(2000, 100.0), (2000 + 860, echo), (2900, factor * 2.0 * echo)])
    got = _sel(env, sep=900, look=30)
    assert [p for p, *_ in got] == ([2000, 2900] if accepted else [2000])


# --- dc_or_lowband's band edges and ratio (_lowband) --------------------------------------


def _flat_spectra(changes: dict[int, float]):
    from rangekit.detect.matched import Spectra

    f = np.linspace(0.0, 22050.0, 513)
    N = np.ones(513)
    for k, v in changes.items():
        N[k] = v
    return Spectra(f, N, N.copy(), 1024), (float(f[100]), float(f[200]))


@pytest.mark.parametrize("edge", [100, 200])
def test_lowband_counts_the_bins_at_the_bands_edges_as_in_band(edge):
    """The band's bins are ``lo <= f <= hi``: a bin 1000x up at either edge is in-band
    power (no flag); one bin past the edge it is out of band (flagged)."""
    sp, band = _flat_spectra({edge: 1000.0})
    assert T._lowband(sp, band) is False
    outside = edge - 1 if edge == 100 else edge + 1
    sp, band = _flat_spectra({outside: 1000.0})
    assert T._lowband(sp, band) is True


@pytest.mark.parametrize(("factor", "flagged"), [(1.01, True), (0.99, False)])
def test_lowband_needs_the_excess_to_exceed_the_bands_power(factor, flagged):
    """Ten bins below the band at ``10 med + s``: their excess ``10 s`` against the band's
    101 bins of power 1, 1 % either side."""
    s = factor * 101.0 / 10.0
    sp, band = _flat_spectra({k: 10.0 + s for k in range(10)})
    assert T._lowband(sp, band) is flagged


def test_lowband_without_bins_in_the_band():
    """A band between two bins holds none: no flag, whatever lies outside."""
    sp, _ = _flat_spectra({k: 1e6 for k in range(10)})
    f = sp.f_hz
    assert T._lowband(sp, (float(f[100]) + 1.0, float(f[100]) + 2.0)) is False
    assert T._lowband(sp, (float(f[100]), float(f[100]))) is True  # one bin


# --- sub-band coverage on FFT-bin edges (_coverage) ----------------------------------------

FS48 = 48000.0


def _bin_probe():
    """A 20 ms sweep at 48 kHz (960 samples: bins of 50 Hz) with its band set to 3-9 kHz:
    sub-band edges every 750 Hz, on bins."""
    return _probe(2000.0, 10000.0, 0.02, fs=FS48, band=(3000.0, 9000.0))


def _coverage_of(boost_bins, j=5000, n=12000, seed=0, band=3):
    """Coverage of an arrival at ``j``: the template with the bins of sub-band ``band``
    (3: bins 105-119) removed and those of ``boost_bins`` 3x up, in white noise 1e-3."""
    p = _bin_probe()
    base = T._base(p, FS48, DEFAULT_BLOCK)
    h = base.template
    S = np.fft.rfft(h)
    S0 = S.copy()
    S[60 + 15 * band : 75 + 15 * band] = 0.0
    for k in boost_bins:
        S[k] = 3.0 * S0[k]
    x = 1e-3 * np.random.default_rng(seed).standard_normal(n)
    seg = np.fft.irfft(S, len(h))
    lo, hi = max(j, 0), min(j + len(h), n)
    x[lo:hi] += seg[lo - j : hi - j]
    sp = welch_spectra(x, fs=FS48, nperseg=base.nperseg)
    W = weighting_response("ml", sp, template_psd=base.template_psd, band_hz=base.band)
    wf = T._weighted(p, FS48, DEFAULT_BLOCK, W, 300)
    return T._coverage(wf.condition(x), j, base, wf, sp), wf


def test_coverage_reads_each_bin_in_one_half_open_sub_band():
    """Sub-band 3 (bins 105-119) removed: its share is missing (coverage 0.77, measured:
    ``1 - share_3`` of the tested share). Bin 120, on the edge between sub-bands 3 and 4,
    belongs to sub-band 4 only: 3x up, the coverage is the same (to 1e-6, measured 6e-9);
    bin 105 (sub-band 3's own lower edge) or 119 3x up makes sub-band 3 present again."""
    c0, wf = _coverage_of([])
    assert 0.6 < c0 < 1.0 - 0.5 * wf.shares[3]  # measured 0.768, share_3 0.224
    assert _coverage_of([120])[0] == pytest.approx(c0, abs=1e-6)
    assert _coverage_of([105])[0] == 1.0
    assert _coverage_of([119])[0] == 1.0


def test_coverage_needs_the_whole_template_inside_the_recording():
    """Judged for onsets ``0 <= j`` with ``j + len(template) <= len(x)``; 1 (undecided)
    otherwise."""
    n = 12000
    c0, wf = _coverage_of([], j=n - 960, n=n)
    assert c0 < 1.0 - 0.5 * wf.shares[3]  # measured 0.765
    assert _coverage_of([], j=n - 959, n=n)[0] == 1.0
    c0, wf = _coverage_of([], j=0, n=n)
    assert c0 < 1.0 - 0.5 * wf.shares[3]
    assert _coverage_of([], j=-1, n=n)[0] == 1.0


def test_expected_separation_is_half_an_emissions_share_of_a_short_recording():
    """With ``expected`` the separation is ``max(duration, min(0.1 s, len / fs / (2
    expected)))``: four 10 ms pings 120 ms apart in 0.6 s, so 75 ms. An echo 60 ms after
    the first (0.8 of it) belongs to it, and the four pings are the arrivals; with a
    separation of 50 ms given it is an arrival and the weakest ping (0.5) is left out."""
    from probecorpus import place

    p = _probe(2000.0, 6000.0, 0.01)
    n = int(0.6 * FS)
    ons = [(0.05 + 0.12 * i) * FS + 0.3 for i in range(4)]
    x = place(p.samples, [*ons, ons[0] + 0.06 * FS], [1.0, 1.0, 1.0, 0.5, 0.8], n)
    x += 1e-3 * np.random.default_rng(1).standard_normal(n)
    a = T.detect_template(x, fs=FS, probe=p, expected=4)
    np.testing.assert_allclose(a.onset, ons, atol=3e-3)  # measured 1.1e-3
    b = T.detect_template(x, fs=FS, probe=p, expected=4, min_separation_s=0.05)
    want = sorted([*ons[:3], ons[0] + 0.06 * FS])
    np.testing.assert_allclose(b.onset, want, atol=8e-3)  # measured 3.9e-3 (the echo)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_snr_of_a_first_arrival_is_over_the_recordings_noise_floor(seed):
    """Before the first arrival the floor is the recording's noise (the Rayleigh scale of
    the whole weighted envelope), not the local window's: ``snr_db = 20 log10(height /
    noise)``, the height the peak's (interpolated: at most 0.03 dB above the sample
    maximum; measured 0.016)."""
    from rangekit.detect.matched import noise_level

    p = _probe(2000.0, 6000.0, 0.02)
    for onset in (3000.0, 3000.37, 9000.6):
        x = _recording(p, [onset], [1.0], 0.03, seed)
        a = T.detect_template(x, fs=FS, probe=p)
        wf = _filter_of(p, x, 441)
        env = np.abs(wf.mf.correlate(wf.condition(x)))
        want = 20.0 * math.log10(env.max() / max(noise_level(env), 1e-6 * env.max()))
        assert 0.0 <= a.snr_db[0] - want < 0.03, (onset, a.snr_db[0], want)


def test_recordings_as_short_as_the_probe():
    """A recording exactly the probe's length is searched (one arrival: the probe itself,
    timed 18.9 samples late, measured: the whole arrival sits in the conditioning FIR's
    edge); one sample shorter is refused; under 3 samples gives no arrival (before the
    length check)."""
    from rangekit.errors import IncompatibleInputError
    from rangekit.signals.probe import Probe

    p = _probe(2000.0, 6000.0, 0.02)
    x = np.asarray(p.samples, dtype=float).copy()
    a = T.detect_template(x, fs=FS, probe=p)
    assert len(a) == 1
    with pytest.raises(IncompatibleInputError):
        T.detect_template(x[:-1], fs=FS, probe=p)
    q = Probe(np.hanning(16), FS)  # 16 samples, a band below 5 kHz
    with pytest.raises(IncompatibleInputError):
        T.detect_template(np.ones(3), fs=FS, probe=q)
    assert len(T.detect_template(np.ones(2), fs=FS, probe=q)) == 0


def test_given_spectra_must_be_at_the_recordings_rate():
    """``spectra`` of this recording gives the default's arrivals exactly; of a recording
    at another rate (or not a Spectra) it is refused."""
    from rangekit.errors import InvalidParameterError

    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3], [1.0], 1e-3, 0)
    base = T._base(p, FS, DEFAULT_BLOCK)
    own = welch_spectra(x, fs=FS, nperseg=base.nperseg)
    a = T.detect_template(x, fs=FS, probe=p)
    b = T.detect_template(x, fs=FS, probe=p, spectra=own)
    np.testing.assert_array_equal(a.onset, b.onset)
    np.testing.assert_array_equal(a.sigma, b.sigma)
    other = welch_spectra(x, fs=48000.0, nperseg=base.nperseg)
    with pytest.raises(InvalidParameterError, match="spectra"):
        T.detect_template(x, fs=FS, probe=p, spectra=other)
    with pytest.raises(InvalidParameterError, match="spectra"):
        T.detect_template(x, fs=FS, probe=p, spectra=own.noise)


def test_a_lookback_of_zero_still_times_the_arrival():
    """``lookback_s=0`` is legal: the first-path search still gets its three lags."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3], [1.0], 1e-3, 0)
    a = T.detect_template(x, fs=FS, probe=p, lookback_s=0.0)
    assert len(a) == 1 and abs(a.onset[0] - 3000.3) < 1e-3  # measured 5.5e-4


def test_only_the_arrival_with_clipped_samples_is_flagged_clipped():
    """Two arrivals 9000 samples apart, the second clipped at 1 (3x over): ``clipped`` on
    the second only (its samples ``[j, j + len(template))``, dilated by the FIR's reach),
    both still timed (measured 9e-4 and 0.24 samples off: the clipped one distorted)."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = np.clip(_recording(p, [3000.3, 12000.6], [0.3, 3.0], 1e-3, 0), -1.0, 1.0)
    a = T.detect_template(x, fs=FS, probe=p)
    assert len(a) == 2 and abs(a.onset[0] - 3000.3) < 2e-3 and abs(a.onset[1] - 12000.6) < 0.5
    assert [bool(f & 1) for f in a.flags] == [False, True]


def test_an_arrival_in_anothers_reverberation_is_reverb_limited():
    """A second arrival 0.15 s after the first, inside its reverberation (decaying noise
    50x the recording's, 0.1 s time constant): its local floor is above REVERB_FACTOR (2)
    times the noise, so ``reverb_limited``; the first arrival's is not."""
    p = _probe(2000.0, 6000.0, 0.02)
    n = 30000
    x = _recording(p, [3000.3, 3000.3 + 0.15 * FS], [1.0, 0.3], 1e-3, 0, n)
    t = np.arange(n)
    decay = np.where(t > 3900, np.exp(-(t - 3900) / (0.1 * FS)), 0.0)
    x += 0.05 * decay * np.random.default_rng(5).standard_normal(n)
    a = T.detect_template(x, fs=FS, probe=p)
    assert len(a) == 2
    assert [bool(f & 32) for f in a.flags] == [False, True]


def test_noise_spectra_is_welchs_with_the_detectors_segment():
    """``noise_spectra`` is the Welch spectrum ``detect_template`` weights by: nperseg
    1024 at 44.1 kHz; giving it changes nothing."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3], [1.0], 1e-3, 2)
    sp = T.noise_spectra(x, fs=FS, probe=p)
    ref = welch_spectra(x, fs=FS, nperseg=1024)
    np.testing.assert_array_equal(sp.f_hz, ref.f_hz)
    np.testing.assert_array_equal(sp.noise, ref.noise)
    a = T.detect_template(x, fs=FS, probe=p)
    b = T.detect_template(x, fs=FS, probe=p, spectra=sp)
    np.testing.assert_array_equal(a.onset, b.onset)


def test_the_side_lobe_pull_is_taken_off_up_to_a_quarter_lobe_and_kept_in_sigma(monkeypatch):
    """The pull (``_leakage``, stubbed here to a given value; the shape term stubbed to 0)
    is taken off the onset when it is at most LEAK_CORRECT_LOBE (1/4) of the main lobe's
    half width, and LEAK_RESIDUAL (1/2) of it stays in sigma (in quadrature); beyond, the
    onset stays and the whole pull is in sigma. At exactly a quarter lobe it is taken off."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3], [1.0], 1e-3, 0)
    quarter = 0.25 * _filter_of(p, x, 441).half_lobe
    monkeypatch.setattr(T, "_unexplained", lambda *a, **k: 0.0)

    def run(pull):
        monkeypatch.setattr(T, "_leakage", lambda *a, **k: pull)
        a = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)
        return a.onset[0], a.sigma[0]

    on0, s0 = run(0.0)
    cases = [
        (0.3, True, 0.15),
        (-0.3, True, 0.15),
        (quarter, True, 0.5 * quarter),
        (1.01 * quarter, False, 1.01 * quarter),
        (5.0, False, 5.0),
    ]
    for pull, taken, kept in cases:
        on, s = run(pull)
        assert on == pytest.approx(on0 - (pull if taken else 0.0), abs=1e-9), pull
        assert s == pytest.approx(math.hypot(s0, kept), rel=1e-9), pull


def test_the_shape_term_is_the_cauchy_schwarz_bound_of_the_unexplained_share(monkeypatch):
    """The envelope timing's shape term is ``sqrt(eps) / (2 pi beta_w)`` (in quadrature),
    ``eps`` the unexplained share (``_unexplained``, stubbed here to a given value)."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3], [1.0], 1e-3, 0)
    beta = _filter_of(p, x, 441).beta
    monkeypatch.setattr(T, "_leakage", lambda *a, **k: 0.0)
    sig = {}
    for eps in (0.0, 1e-4, 0.04):
        monkeypatch.setattr(T, "_unexplained", lambda *a, e=eps, **k: e)
        sig[eps] = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0).sigma[0]
    for eps in (1e-4, 0.04):
        want = math.hypot(sig[0.0], math.sqrt(eps) / (2.0 * math.pi * beta))
        assert sig[eps] == pytest.approx(want, rel=1e-9), eps


def test_the_coherent_shape_term_uses_the_rms_frequency(monkeypatch):
    """An in-phase 20 Hz-20 kHz arrival (weight 1): its shape term is ``sqrt(eps_odd) /
    (2 pi F_w)`` (``_odd_eps`` stubbed to a given value), in quadrature; the envelope's
    share (``_unexplained``) does not enter."""
    p = _probe(20.0, 20000.0, 0.1)
    x = _recording(p, [3000.0], [1.0], 1e-3, 0)
    f_rms = _filter_of(p, x, 882).f_rms
    monkeypatch.setattr(T, "_unexplained", lambda *a, **k: 0.5)
    sig = {}
    for eps in (0.0, 1e-4, 0.04):
        monkeypatch.setattr(T, "_odd_eps", lambda *a, e=eps, **k: e)
        sig[eps] = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0).sigma[0]
    assert sig[0.0] < 1e-4  # the envelope's 0.5 not counted: measured 3.9e-5
    for eps in (1e-4, 0.04):
        want = math.hypot(sig[0.0], math.sqrt(eps) / (2.0 * math.pi * f_rms))
        assert sig[eps] == pytest.approx(want, rel=1e-9), eps


AMBIGUITY_CASES = [(0.37, 0.25, True), (0.38, 0.25, False), (0.33, 0.25, True), (0.33, 0.2, False)]


@pytest.mark.parametrize(("g", "rel", "ambiguous"), AMBIGUITY_CASES)
def test_a_first_path_within_1_5_of_its_threshold_is_ambiguous(g, rel, ambiguous):
    """A direct path at ``g`` of a reflection 4 ms later: chosen (above ``rel_threshold``
    of the strongest), and ``ambiguous_first_path`` when its height is under
    AMBIGUOUS_MARGIN (1.5) times the threshold: confidence / rel 1.48 is, 1.52 is not
    (measured 1.482 and 1.522); 0.33 is within 1.5 x 0.25, not within 1.5 x 0.2."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = _recording(p, [3000.3, 3000.3 + 0.004 * FS], [g, 1.0], 1e-3, 0)
    a = T.detect_template(x, fs=FS, probe=p, rel_threshold=rel)
    assert len(a) == 1 and abs(a.onset[0] - 3000.3) < 2e-3  # measured <= 9e-4
    assert a.confidence[0] == pytest.approx(g, abs=2e-3)  # measured 4e-4
    assert bool(a.flags[0] & 4) is ambiguous


@pytest.mark.parametrize("band", [0, 1, 6, 7])
def test_coverage_tests_only_sub_bands_of_a_32nd_of_the_share(band):
    """A sub-band is tested only when its expected share is at least ``1 / (4 N_SUBBANDS)``
    (1/32): the 3-9 kHz band's outer sub-bands (shares 0.016 and 0.017) removed leave
    coverage 1; sub-bands 1 and 6 (0.081 and 0.058, the latter under 1/16) removed, the
    coverage is the tested share left over the tested share, to 1e-9."""
    c, wf = _coverage_of([], band=band)
    sh = wf.shares
    tested = sh >= 1.0 / 32.0
    assert list(np.flatnonzero(~tested)) == [0, 7]
    if band in (0, 7):
        assert c == 1.0
    else:
        assert c == pytest.approx(1.0 - sh[band] / sh[tested].sum(), abs=1e-9)
        assert c < 1.0 - 0.5 * sh[band]  # measured 0.916 and 0.940


def test_the_plain_matched_filter_neither_masks_clipping_nor_weighs_noise():
    """``weighting="none"``: no conditioning, so no clipped-sample mask (a clipped arrival
    is not flagged ``clipped``) and no noise spectrum (strong 50 Hz hum is not flagged
    ``dc_or_lowband``); the weighted filter flags both."""
    p = _probe(2000.0, 6000.0, 0.02)
    x = np.clip(_recording(p, [3000.3, 12000.6], [0.3, 3.0], 1e-3, 0), -1.0, 1.0)
    plain = T.detect_template(x, fs=FS, probe=p, weighting="none")
    ml = T.detect_template(x, fs=FS, probe=p)
    assert len(plain) == 2 and [bool(f & 1) for f in plain.flags] == [False, False]
    assert [bool(f & 1) for f in ml.flags] == [False, True]
    y = _recording(p, [3000.3], [1.0], 1e-3, 0)
    y += 0.3 * np.sin(2 * np.pi * 50.0 * np.arange(len(y)) / FS) * np.hanning(len(y))
    plain = T.detect_template(y, fs=FS, probe=p, weighting="none")
    ml = T.detect_template(y, fs=FS, probe=p)
    assert plain.flags.tolist() == [0] and ml.flags.tolist() == [64]
    assert abs(plain.onset[0] - 3000.3) < 2e-3  # measured 5e-4


@pytest.mark.parametrize("cos_phase", [1.0, 0.7, 0.4])
def test_the_coherent_and_envelope_timings_blend_by_the_weight(monkeypatch, cos_phase):
    """A 20 Hz-20 kHz arrival whose coherent lag is stubbed ``d = 0.05`` samples after the
    envelope's, at ``|cos phase|`` 1, 0.7 and 0.4 (weights 1, 0.546, 0): the onset moves by
    ``w d``; the CRB and interpolation terms blend linearly, ``w s_coh + (1 - w) s_crb``
    and ``w coherent_rms + (1 - w) interp_rms``; the disagreement beyond both timings' own
    errors, ``sqrt(d^2 - s_crb^2 - interp_rms^2 - coherent_rms^2)``, enters in quadrature
    (shape and pull stubbed to 0), and the transducer term is ``(1 - w) A / (2 pi beta) +
    w A / (2 pi F)``. All to 1e-9."""
    p = _probe(20.0, 20000.0, 0.1)
    x = _recording(p, [3000.0], [1.0], 1e-3, 0)
    wf = _filter_of(p, x, 882)
    for name in ("_unexplained", "_odd_eps", "_leakage"):
        monkeypatch.setattr(T, name, lambda *a, **k: 0.0)
    monkeypatch.setattr(T, "coherent_lag", lambda c, lag, reach: None)
    env = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)  # envelope only
    d = 0.05
    monkeypatch.setattr(T, "coherent_lag", lambda c, lag, reach: (lag + d, cos_phase))
    a0 = T.detect_template(x, fs=FS, probe=p, transducer_ripple_db=0.0)
    a6 = T.detect_template(x, fs=FS, probe=p)
    w = min(1.0, max(0.0, (cos_phase - 0.5) / (math.cos(math.pi / 6.0) - 0.5)))
    snr = 10.0 ** (env.snr_db[0] / 20.0)
    s_env = 1.0 / (2.0 * math.pi * wf.beta * snr)
    s_coh = 1.0 / (2.0 * math.pi * wf.f_rms * snr)
    assert env.sigma[0] == pytest.approx(math.hypot(s_env, wf.interp_rms), rel=1e-9)
    assert a0.onset[0] == pytest.approx(env.onset[0] + w * d, abs=1e-9)
    s_def = math.sqrt(max(0.0, d**2 - s_env**2 - wf.interp_rms**2 - wf.coherent_rms**2))
    assert s_def > 0.04  # measured 0.050
    crb = w * s_coh + (1.0 - w) * s_env
    interp = w * wf.coherent_rms + (1.0 - w) * wf.interp_rms
    want = math.sqrt(crb**2 + interp**2 + (s_def if w > 0 else 0.0) ** 2)
    assert a0.sigma[0] == pytest.approx(want, rel=1e-9)
    s_td = (1.0 - w) * _ripple_6db(wf.beta) + w * _ripple_6db(wf.f_rms)
    assert a6.sigma_transducer[0] == pytest.approx(s_td, rel=1e-9)


@pytest.mark.parametrize("side", ["after", "before"])
def test_clipped_samples_count_within_the_fir_reach_of_the_arrival(side):
    """A two-sample click at the rail (clipped, zeroed before filtering) counts for an
    arrival when the FIR, ``reach`` samples either way, carries it into the arrival's
    samples ``[j, j + len(template))``: one sample nearer than that boundary it is
    ``clipped``, at the boundary it is not."""
    p = _probe(2000.0, 6000.0, 0.02)
    j = 8000
    x0 = _recording(p, [float(j)], [0.3], 1e-3, 0)
    a = T.detect_template(x0, fs=FS, probe=p)
    assert int(round(a.onset[0])) == j
    reach = _filter_of(p, x0, 441).reach
    n = len(p.samples)
    edge = j + n + reach if side == "after" else j - reach - 2  # first click start not counted
    step = -1 if side == "after" else 1
    got = []
    for c in (edge + step, edge):
        x = x0.copy()
        x[c : c + 2] = 1.0
        b = T.detect_template(x, fs=FS, probe=p)
        assert len(b) == 1 and abs(b.onset[0] - j) < 1e-3  # measured 5e-4
        got.append(bool(b.flags[0] & 1))
    assert got == [True, False]
