"""Arrivals timed by a transducer fit whose model is chosen from the recording.

:func:`rangekit.detect.matched.detect_matched` with ``model=`` fits every arrival with
one transducer model (two equal resonators, :class:`rangekit.detect.pathfit.
ResonatorModel`). A transducer of another shape then comes back as a bias that its sigma
does not show (``docs/theory/ultrasonic.md``, "What the model does not hold").
:func:`detect_fitted` fits the first arrivals of each transducer group with two nested
descriptions, one resonator per element and two stagger-tuned resonators per element
(:class:`rangekit.detect.stagger.StaggerModel`), and keeps the one the data favour.

**Choice.** Per group (one Tx and one receiver) the first ``N_TEST`` arrivals above the
low-SNR level are fitted with both models on the same segment (the stagger fit from the
resonator fit's paths, moved by the two models' difference of group delay; where the
resonator fit holds paths weaker than ``STRONG`` of its strongest, both models also
without them). Each model's fit is scored by Schwarz's criterion ``chi2 + 3 ln(n)
n_paths`` (its best of the path choices) and the difference ``D_w`` between them (0 where
the stagger is worse: it nests the resonator to a misfit of 1e-4, so worse means stuck)
gives the log Bayes factor of the stagger's two further parameters, shared by the group,
``L = (n_w median(D_w) - 2 n_free) / 2 - ln N`` (``n_free`` the pairs of free fits, whose
two extra parameters each lower the stagger's chi-square by 2 on average when the
resonator is right; ``N`` the samples fitted; the median so that one stuck window does
not decide), and the posterior probability of the stagger model ``w = 1 / (1 +
exp(-L))``. The stagger model (where ``w > P_STAGGER``) or else the resonator times
every arrival of the group (held at its running estimate after ``N_FREE_FITS`` free
fits, pooled as in :func:`rangekit.detect.pathfit.pool_fits`; the stagger's free fits
refitted at the group's robust estimate).

**Sigma.** Besides the chosen model's Cramér-Rao bound (and misfit term,
:func:`rangekit.detect.matched._fit_sigma`), each onset's variance gets the model
uncertainty ``(1 - w_chosen) d^2``, ``d^2`` the mean square difference of the two models'
onsets over the tested arrivals: the expected square error of reporting one model's
onset when the other one is right with probability ``1 - w_chosen`` (Bayesian model
averaging, Hoeting et al. 1999, *Statistical Science* 14(4), eq. 1-2). A transducer of
higher order than both models is fitted to within the noise but late by about ``d``;
:func:`order_terms` recognises it by the stagger fits' split (a band flatter than a
maximally flat pair, pooled over the receivers of one transmitter) and
:func:`with_order_terms` adds the next order's step to sigma (a transducer term,
``Arrivals.sigma_transducer``).

**Transducer family.** How sure the model choice is rests on a prior: Schwarz's ``ln N``
is the Occam factor of the stagger's two further parameters for a prior as wide as one
sample's worth of data. For the resonant piezo of the papers (``transducer_family=
"resonator"``, the default) that is the right prior: its onsets keep the sigma above.
A transducer of another shape at low Q and SNR is where it fails: at Q 4 the waveform
does not tell a coupled pair from a resonator, ``ln N`` makes the resonator "certain",
and 8 of 30 receivers came back 10-12 mm late at a sigma of 1-2 mm (coupled, Q 4, 10
dB). ``transducer_family="unknown"`` weighs the models by the data's evidence alone,
Akaike's weight ``w_A = 1 / (1 + exp(-(n_w median(D_w) - 2 n_free) / 2))`` (the same
evidence without ``- ln N``; Burnham & Anderson 2002, *Model Selection and Multimodel
Inference*, sec. 4.3, the model-averaged variance), and counts only the part of ``d^2``
that is a model's bias: per tested arrival ``max(d^2 - (sigma_s^2 - sigma_r^2), 0)``, the
two onsets' difference beyond what noise gives where the resonator is right (Hausman
1978, *Econometrica* 46(6), the difference of an efficient and a consistent estimator),
so the variance added is ``(1 - w_A,chosen) median(d^2 - dv)``. The model chosen and the
onsets are the same for both values; only ``sigma`` differs (wider for a resonator:
docs/accuracy.md, "Transducer family").

Examples
--------
>>> from rangekit.detect.matched import coded_template
>>> from rangekit.detect.pathfit import ResonatorModel
>>> from rangekit.detect.stagger import StaggerModel
>>> from rangekit.signals.barker import CodedBurst, burst_waveform
>>> from rangekit.signals.transducer import BandpassTransducer
>>> fs = 192000.0
>>> rng = np.random.default_rng(1)
>>> t = BandpassTransducer(q=12.0)
>>> x = np.zeros(6 * 8000)
>>> for w in range(6):
...     x[w * 8000 + 3000 : w * 8000 + 3101] = burst_waveform(CodedBurst(fs=fs))
>>> x = t.apply(t.apply(x, fs=fs), fs=fs) + 0.01 * rng.standard_normal(len(x))
>>> models = (ResonatorModel.for_burst(fs=fs), StaggerModel.for_burst(fs=fs))
>>> arr = detect_fitted(x, fs=fs, template=coded_template(fs=fs), models=models,
...                     windows=np.array([[w * 8000, (w + 1) * 8000] for w in range(6)]))
>>> bool(np.all(np.abs(arr.onset - 3000 - 8000 * np.arange(6)) < 3 * arr.sigma))
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from rangekit import _validate as V
from rangekit.detect import matched as M
from rangekit.detect.pathfit import PathFit, fit_arrival, kernel_by_length, pool_fits
from rangekit.errors import InvalidParameterError
from rangekit.types import Arrivals, flag_bit

__all__ = [
    "N_TEST",
    "TRANSDUCER_FAMILIES",
    "ChannelFit",
    "check_shapes",
    "check_transducer_family",
    "detect_coded",
    "detect_fitted",
    "fit_channel",
    "order_terms",
    "transducer_models",
    "with_order_terms",
]

#: The stagger model times a group only at this posterior probability or more (the
#: resonator, two parameters fewer, is the default; below it the resonator's onsets carry
#: the model-choice variance ``w_stagger d^2``).
P_STAGGER = 0.9
#: The comparison's fits stop within 0.05 noise variances of their optimum (its
#: evidence is counted in units of several).
TEST_FIT = {"tol": 1e-3, "max_iter": 30}
#: A stagger fit is also tried without the resonator fit's paths weaker than this
#: fraction of its strongest (paths a resonator adds to mimic a longer response).
STRONG = 0.5

#: Arrivals per group fitted with both transducer models before one is chosen.
N_TEST = 3
#: Free fits of a group (per model) before later arrivals hold the running estimate.
N_FREE_FITS = M.N_FREE_FITS


def _fit_one(x, lag, model, sigma, acc, q0, kw, low, theta=None, start=None) -> PathFit | None:
    """One model's fit of an arrival; updates that model's running estimate ``acc``.

    ``acc`` is ``[sum info, sum info theta, n, theta_held, fits]`` over the group's fits
    above the low-SNR level (the scheme of ``rangekit.detect.matched._fit_window`` for any
    number of transducer parameters), and a sixth item True where ``theta_held`` was given
    (a forced consensus shape: never refreshed from the group's own fits).
    """
    p = model.n_theta
    fit = None
    if acc and acc[2] >= N_FREE_FITS:
        fit = fit_arrival(x, lag, model=model, sigma=sigma, theta=acc[3], hold=True, **kw)
        if fit is not None:
            dev = fit.theta_hat - acc[3]
            if float(dev @ fit.info @ dev) > 8.0 * p:
                fit = None
    if fit is None:
        if theta is not None:
            fit = fit_arrival(x, lag, model=model, sigma=sigma, theta=theta, start=start, **kw)
        else:
            fit = fit_arrival(x, lag, model=model, sigma=sigma, q0=q0, **kw)
    _accumulate(acc, fit, model, low)
    return fit


def _accumulate(acc, fit, model, low) -> None:
    """Add ``fit`` to the running estimate ``acc`` (above the low-SNR level)."""
    p = model.n_theta
    if fit is not None and fit.snr >= low and np.linalg.det(fit.info) > 0:
        if not acc:
            acc.extend([np.zeros((p, p)), np.zeros(p), 0, None, []])
        acc[0] = acc[0] + fit.info
        acc[1] = acc[1] + fit.info @ fit.theta_hat
        acc[2] += 1
        acc[4].append(fit)
        n = acc[2]
        pinned = len(acc) > 5 and acc[5]  # held at a consensus given from outside
        if n >= N_FREE_FITS and not pinned and (acc[3] is None or n & (n - 1) == 0):
            if model.family == "resonator":
                try:
                    acc[3] = np.linalg.solve(acc[0], acc[1])
                except np.linalg.LinAlgError:
                    acc[3] = fit.theta_hat
            else:  # four parameters: a free fit gone astray must not set the estimate
                acc[3] = _robust_theta(acc[4])


def _robust_theta(fits) -> np.ndarray:
    """Information-weighted mean ``theta`` of ``fits`` over those within 4 sigma of it
    (iterated from the median; the median itself if fewer than two agree)."""
    th = np.array([f.theta_hat for f in fits])
    w = np.array([f.info for f in fits])
    mean = np.median(th, axis=0)
    keep = np.ones(len(th), bool)
    for _ in range(5):
        dev = th - mean
        d2 = np.einsum("ni,nij,nj->n", dev, w, dev)
        new = d2 <= 8.0 * th.shape[1]
        if new.sum() < 2:
            return mean
        keep = new
        try:
            mean = np.linalg.solve(w[keep].sum(axis=0), np.einsum("nij,nj->i", w[keep], th[keep]))
        except np.linalg.LinAlgError:
            return mean
    return mean


def _stagger_start(fit_r: PathFit, res_model, stag_model):
    """Starting ``theta`` and path onsets of a stagger fit from a resonator fit."""
    from rangekit.detect.stagger import group_delay_samples

    th = stag_model.theta_start(fit_r.q, fit_r.f0_hz)
    shift = group_delay_samples(res_model, fit_r.theta_lin) - group_delay_samples(stag_model, th)
    # Every path of the resonator fit (also its small ones): the two models are compared
    # on the same paths, or a path the resonator fit added would count for the stagger.
    return th, fit_r.onsets + shift


#: The values of ``transducer_family`` (:func:`fit_channel`): what a user knows of the
#: transducers' family before measuring (module doc, **Transducer family**).
TRANSDUCER_FAMILIES = ("resonator", "unknown")


def check_transducer_family(
    transducer_family: str, *, fit: bool = True, fit_name: str = "fit_transducers=True"
) -> str:
    """``transducer_family`` if it is one of :data:`TRANSDUCER_FAMILIES` and, when it is
    not the default, the arrivals are timed by the transducer fit (``fit``; ``fit_name``
    says how the caller's user asks for it, for the message).

    Examples
    --------
    >>> check_transducer_family("unknown")
    'unknown'
    >>> check_transducer_family("piezo")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: transducer_family='piezo' must be one of ...
    >>> check_transducer_family("unknown", fit=False)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: transducer_family='unknown' applies to the ...
    """
    if not isinstance(transducer_family, str) or transducer_family not in TRANSDUCER_FAMILIES:
        raise InvalidParameterError(
            f"{transducer_family=} must be one of {', '.join(TRANSDUCER_FAMILIES)}"
        )
    if transducer_family != "resonator" and not fit:
        raise InvalidParameterError(
            f"{transducer_family=} applies to the transducer fit only ({fit_name})"
        )
    return transducer_family


def _logistic(v: float) -> float:
    """``1 / (1 + exp(-v))``, ``v`` held within +-50."""
    return 1.0 / (1.0 + math.exp(-max(min(v, 50.0), -50.0)))


class _Group:
    """Per transducer group: both models' running estimates and the model comparison
    (``w``: the chosen model's Schwarz weight; ``w_var``: its Akaike weight, used with
    ``transducer_family="unknown"``; ``dv``: per test, the noise variance of the two
    onsets' difference where the resonator is right)."""

    def __init__(self) -> None:
        self.acc: dict[str, list] = {"resonator": [], "stagger": []}
        self.tests: list[tuple[float, bool, float, int]] = []
        self.dv: list[float] = []  # per test: the onsets' difference's noise variance
        self.family: str | None = None
        self.w = 1.0
        self.w_var = 1.0

    def decide(self, force=None) -> None:
        if isinstance(force, tuple):  # the receivers' consensus shape
            self.family, self.w = force[0], 1.0
            self.w_var = self.w
            return
        if force is not None:
            self.family, self.w = force, 0.5
            self.w_var = self.w
            return
        if not self.tests:
            self.family, self.w = "resonator", 1.0
            self.w_var = self.w
            return
        d = np.array([t[0] for t in self.tests])
        n_free = sum(t[1] for t in self.tests)
        n = sum(t[3] for t in self.tests)
        # The median window's evidence, times the windows: one window whose resonator
        # fit stuck in a poor optimum must not decide for the group.
        evidence = 0.5 * (len(d) * float(np.median(d)) - 2.0 * n_free)
        logbf = evidence - math.log(max(n, 2))
        w_s = _logistic(logbf)
        self.family = "stagger" if w_s > P_STAGGER else "resonator"
        self.w = w_s if self.family == "stagger" else 1.0 - w_s
        # transducer_family="unknown": the model-choice variance weighs the models by the
        # data's evidence alone (the Akaike weight, without Schwarz's ln N Occam factor,
        # whose size rests on the prior width of the stagger's split: it alone made the
        # resonator "certain" for coupled Q 4 transducers at 10 dB that it timed 11 mm
        # late).
        w_a = _logistic(evidence)
        self.w_var = w_a if self.family == "stagger" else 1.0 - w_a

    def clearly_resonator(self) -> bool:
        """Before ``N_TEST`` tests: the resonator wins even if the remaining tests gave the
        largest evidence seen so far (the median is then at most that), at odds of 99:1."""
        d = max(t[0] for t in self.tests)
        scale = N_TEST / len(self.tests)
        n = sum(t[3] for t in self.tests) * scale
        n_free = sum(t[1] for t in self.tests) * scale
        return 0.5 * N_TEST * d - n_free - math.log(max(n, 2)) < -math.log(99.0)

    @property
    def d2(self) -> float:
        return float(np.median([t[2] ** 2 for t in self.tests])) if self.tests else 0.0

    @property
    def d2_excess(self) -> float:
        """The median over the tested arrivals of the models' squared onset difference
        beyond what noise gives where the resonator is right (Hausman 1978: the
        difference of two estimators, one efficient under the null, has the difference
        of their variances): the part of ``d2`` that is a model's bias."""
        if not self.tests:
            return 0.0
        d2 = [max(t[2] ** 2 - v, 0.0) for t, v in zip(self.tests, self.dv, strict=True)]
        return float(np.median(d2))


def detect_fitted(x: np.ndarray, **kw) -> Arrivals:
    """First-path arrivals of one channel, timed by the transducer fit of the chosen model.

    :func:`fit_channel`'s arrivals; keyword arguments as there.
    """
    return fit_channel(x, **kw).arrivals


@dataclass(frozen=True)
class ChannelFit:
    """:func:`fit_channel`'s result: the arrivals and the stagger shapes it chose.

    Attributes
    ----------
    arrivals : Arrivals
        As :func:`rangekit.detect.matched.detect_matched` with ``model``.
    family : ndarray of str, shape (n,)
        The transducer model that timed each arrival.
    group : list
        Each arrival's group label.
    shapes : dict
        Per group that chose the stagger model: its robust ``theta`` and that estimate's
        covariance (the inverse of the summed information of its fits).
    spread : dict
        Per group whose first arrivals were fitted with both models: ``(d2, split,
        split_var)``, the mean square difference of the two models' onsets (samples^2),
        the stagger fits' robust ``Re nu / a^2`` and its variance (:func:`order_terms`).
    """

    arrivals: Arrivals
    family: np.ndarray
    group: list
    shapes: dict
    spread: dict = field(default_factory=dict)


@kernel_by_length
def fit_channel(
    x: np.ndarray,
    *,
    fs: float,
    template: np.ndarray,
    models: Sequence,
    windows: np.ndarray | None = None,
    search: tuple[int, int] | None = None,
    k_noise: float = M.DEFAULT_K_NOISE,
    rel_threshold: float = M.DEFAULT_REL_THRESHOLD,
    k_detect: float = M.DEFAULT_K_DETECT,
    block: int = M.DEFAULT_BLOCK,
    q0: float = 4.0,
    groups: Sequence[int] | None = None,
    pool: bool = True,
    force: dict | None = None,
    transducer_family: str = "resonator",
) -> ChannelFit:
    """First-path arrivals of one channel, timed by the transducer fit of the chosen model.

    Parameters
    ----------
    x : ndarray
        One channel of the recording.
    fs : float
        Sample rate in Hz.
    template : ndarray
        Matched-filter template that finds the arrivals (:func:`rangekit.detect.matched.
        coded_template`); the fit times them.
    models : sequence
        ``(ResonatorModel, StaggerModel)``: the two descriptions of the transducers
        (module doc); ``(ResonatorModel,)`` or a stagger model of None fits the
        resonator only, as :func:`rangekit.detect.matched.detect_matched` does.
    windows, search, k_noise, rel_threshold, k_detect, block, q0, groups, pool
        As :func:`rangekit.detect.matched.detect_matched` (``groups``: windows with
        equal labels went through the same transducers; the model is chosen and
        ``theta`` pooled per group; ``pool=False``: every window on its own).
    force : dict, optional
        Group label -> ``"resonator"`` (those groups are timed by the resonator whatever
        the comparison says, with the model-choice variance of an undecided choice, ``w
        = 1/2``) or ``("stagger", theta)`` (by the stagger model held at ``theta`` from
        the first arrival on); what :func:`check_shapes` returns.
    transducer_family : {"resonator", "unknown"}
        What is known of the transducers' family before measuring (module doc,
        **Transducer family**): ``"resonator"`` (default) the resonant piezo of the
        papers, whose model-choice variance weighs the models by Schwarz's criterion;
        ``"unknown"`` weighs them by Akaike's (a transducer of either shape, at the
        price of a wider sigma for a resonator). Only ``sigma`` differs.

    Returns
    -------
    ChannelFit
        The arrivals (as :func:`rangekit.detect.matched.detect_matched` with ``model``;
        ``sigma`` includes the model-choice term, module doc) and the chosen models.
    """
    fs = V.sample_rate(fs)
    transducer_family = check_transducer_family(transducer_family)
    x = M._check_x("x", x)  # float32 recordings stay float32 (fits read float64 segments)
    res_model = models[0]
    stag_model = models[1] if len(models) > 1 else None
    mf = M.matched_filter(template, block=block)
    if windows is None:
        windows = np.array([[0, len(x)]])
    windows = np.asarray(windows, dtype=np.int64).reshape(-1, 2)
    lo, hi = (None, None) if search is None else (int(search[0]), int(search[1]))
    m = len(mf.self_response) // 2
    spans = M._window_spans(windows, len(x), lo, hi, m)
    corr = M._window_correlations(x, template, spans, block=block)
    noise_scale = 1.0 / math.sqrt(mf.energy)
    labels = np.zeros(len(windows), dtype=np.int64) if groups is None else np.asarray(groups)
    if len(labels) != len(windows):
        raise InvalidParameterError(f"groups has {len(labels)} labels for {len(windows)} windows")
    low = M.LOW_SNR_FACTOR * k_detect
    state: dict = {}
    rows: list[list] = []
    fits: list[dict] = []
    keys: list = []
    sigmas: list[float] = []
    lims: list[tuple[int, int]] = []
    early: list[bool] = []
    for w, (s0, s1) in enumerate(windows):
        s0, s1 = max(0, int(s0)), min(len(x), int(s1))
        a, b = (int(v) for v in spans[w])
        if s1 - s0 < 3 or b - a < 3:
            continue
        cw, noise, env = corr[w]
        l_, h_ = (0, s1 - s0) if lo is None else (lo, hi)
        p = M.first_path(
            cw, lo=l_ - (a - s0), hi=h_ - (a - s0), noise=noise, k_noise=k_noise,
            rel_threshold=rel_threshold, k_detect=k_detect, self_response=mf.self_response,
            env=env,
        )  # fmt: skip
        if p is None or M._silent_input(x, a + int(round(p.lag)), mf.n_taps):
            continue
        sigma = M._sample_noise(x[s0 : max(s0, a + int(p.lag) - mf.n_taps)])
        if not 0.1 * noise * noise_scale <= sigma <= 2.0 * noise * noise_scale:
            sigma = noise * noise_scale
        key = int(labels[w]) if pool else ("w", w)
        g = state.get(key)
        if g is None:
            g = state[key] = _Group()
            fk = force.get(key) if force else None
            if isinstance(fk, tuple):  # held at the consensus from the first arrival
                g.decide(fk)
                th = np.asarray(fk[1], dtype=np.float64)
                p_ = len(th)
                g.acc["stagger"].extend(
                    [np.zeros((p_, p_)), np.zeros(p_), N_FREE_FITS, th, [], True]
                )
        kw = {"k_noise": k_noise, "rel_threshold": rel_threshold, "lo": s0 + l_, "hi": s0 + h_}
        lag = a + p.lag
        got: dict[str, PathFit | None] = {}
        if g.family != "stagger":
            got["resonator"] = _fit_one(x, lag, res_model, sigma, g.acc["resonator"], q0, kw, low)
        fr = got.get("resonator")
        if stag_model is not None and g.family is None and fr is not None:
            th, start = _stagger_start(fr, res_model, stag_model)
            lag_s = fr.n0 + stag_model.pre
            n_seg = len(x[fr.n0 : fr.n0 + res_model.segment])
            pen = 3.0 * math.log(n_seg)  # BIC: onset and complex amplitude per path
            strong = fr.amplitudes >= STRONG * fr.amplitudes.max()
            if g.acc["stagger"] and g.acc["stagger"][2] >= N_FREE_FITS:
                starts = [start]
            else:
                # The resonator fit may have added a weak path to mimic a longer response
                # (the stagger's shape): try the stagger without the weak paths too.
                starts = [start] + ([start[strong]] if not strong.all() else [])
            fs_ = None
            for st_ in starts:
                cand = _fit_one(
                    x, lag_s, stag_model, sigma, [] if len(starts) > 1 else g.acc["stagger"],
                    q0, {**kw, **TEST_FIT}, low, theta=th, start=st_,
                )  # fmt: skip
                if cand is not None and (
                    fs_ is None or cand.chi2 + pen * cand.n_paths < fs_.chi2 + pen * fs_.n_paths
                ):
                    fs_ = cand
            if len(starts) > 1 and fs_ is not None:
                _accumulate(g.acc["stagger"], fs_, stag_model, low)
            got["stagger"] = fs_
            if fs_ is not None and fs_.n0 == fr.n0 and fr.snr >= low:
                bic_r = fr.chi2 + pen * fr.n_paths
                if len(starts) > 1:  # the same choice of paths for the resonator
                    alt = fit_arrival(
                        x, lag_s, model=res_model, sigma=sigma, theta=fr.theta_lin,
                        start=fr.onsets[strong], max_paths=int(strong.sum()), **TEST_FIT, **kw,
                    )  # fmt: skip
                    if alt is not None and alt.n0 == fr.n0:
                        bic_r = min(bic_r, alt.chi2 + pen * alt.n_paths)
                d = bic_r - (fs_.chi2 + pen * fs_.n_paths)
                d = max(d, 0.0)  # the stagger nests the resonator to 1e-4: worse = stuck
                free = fr.n_par > 3 * fr.n_paths and fs_.n_par > 3 * fs_.n_paths
                # Hausman (1978): where the resonator is right, the two onsets differ by
                # noise of variance var(stagger) - var(resonator) (the resonator efficient).
                dv = max(fs_.sigma**2 - fr.sigma**2, 0.0)
                g.tests.append((d, free, fs_.onset - fr.onset, n_seg))
                g.dv.append(dv)
            if len(g.tests) >= N_TEST or (len(g.tests) >= 2 and g.clearly_resonator()):
                g.decide(force.get(key) if force else None)
        elif g.family == "stagger":
            got["stagger"] = _fit_one(x, lag, stag_model, sigma, g.acc["stagger"], q0, kw, low)
        any_fit = next((f for f in got.values() if f is not None), None)
        top = float(env[int(round(p.strongest_lag))])
        rows.append([a + p.lag, math.inf, p.snr, p.height / top, w])
        sigmas.append(sigma)
        lims.append((s0 + l_, s0 + h_))
        fits.append(got)
        keys.append(key)
        first = (any_fit.onset if any_fit is not None else a + p.lag) - a
        early.append(
            M._earlier_candidate(
                cw, lo=l_ - (a - s0), first=first, noise=noise, reach=mf.n_taps,
                k=0.5 * (k_detect + k_noise), rel=rel_threshold, env=env,
            )
        )  # fmt: skip
    for key, g in state.items():
        if g.family is None:
            g.decide(force.get(key) if force else None)
    chosen: list[PathFit | None] = []
    for got, key in zip(fits, keys, strict=True):
        fam = state[key].family
        f = got.get(fam)
        if f is None:  # the chosen model found nothing here: the other one's fit
            f = next((v for v in got.values() if v is not None), None)
        chosen.append(f)
    if pool and stag_model is not None:
        # Stagger groups: the free fits (four parameters each, possibly astray) are
        # refitted holding the group's robust estimate, so every onset is a fit at it.
        for key, g in state.items():
            if g.family != "stagger" or len(g.acc["stagger"]) < 5 or not g.acc["stagger"][4]:
                continue
            th = _robust_theta(g.acc["stagger"][4])
            for i, (k, f) in enumerate(zip(keys, chosen, strict=True)):
                if k == key and f is not None and f.family == "stagger" and f.n_par > 3 * f.n_paths:
                    lag_i = f.n0 + stag_model.pre
                    kw = {"k_noise": k_noise, "rel_threshold": rel_threshold, "lo": lims[i][0],
                          "hi": lims[i][1]}  # fmt: skip
                    new = fit_arrival(x, lag_i, model=stag_model, sigma=sigmas[i], theta=th,
                                      hold=True, **kw)  # fmt: skip
                    if new is not None:
                        chosen[i] = new
    if pool:
        for key in state:
            for fam in ("resonator", "stagger"):
                idx = [
                    i
                    for i, (k, f) in enumerate(zip(keys, chosen, strict=True))
                    if k == key and f is not None and f.family == fam
                ]
                if len(idx) > 1:
                    pooled, _ = pool_fits([chosen[i] for i in idx])
                    for i, f in zip(idx, pooled, strict=True):
                        chosen[i] = f
    flags = np.zeros(len(rows), dtype=np.int64)
    d2 = {key: g.d2 for key, g in state.items()}
    for i, f in enumerate(chosen):
        if f is not None:
            g = state[keys[i]]
            if stag_model is None:
                extra = 0.0
            elif transducer_family == "resonator":
                extra = (1.0 - g.w) * d2[keys[i]]
            else:  # "unknown": the models weighed by Akaike, the bias part of d^2 only
                extra = (1.0 - g.w_var) * g.d2_excess
            rows[i][0] = f.onset
            rows[i][1] = math.sqrt(M._fit_sigma(f, fs) ** 2 + extra)
            rows[i][2] = f.snr
            rows[i][3] = float(f.amplitudes[f.first] / f.amplitudes.max())
            flags[i] |= M._fit_flags(f)
        else:
            beta = M.rms_bandwidth_hz(mf.template, fs=fs)
            rows[i][1] = fs / (2.0 * math.pi * beta * max(rows[i][2], 1e-12))
            flags[i] |= flag_bit("poor_match")  # nothing the model could fit
        if rows[i][2] < low:
            flags[i] |= flag_bit("low_snr")
        if early[i]:
            flags[i] |= flag_bit("ambiguous_first_path")
    shapes = {}
    for key, g in state.items():
        acc = g.acc["stagger"]
        if g.family == "stagger" and acc and acc[4]:
            try:
                shapes[key] = (_robust_theta(acc[4]), np.linalg.inv(acc[0]))
            except np.linalg.LinAlgError:
                pass
    spread = {}
    for key, g in state.items():
        acc = g.acc["stagger"]
        if g.tests and acc and acc[4]:
            try:
                var = float(np.linalg.inv(acc[0])[2, 2])
            except np.linalg.LinAlgError:
                continue
            spread[key] = (g.d2, float(_robust_theta(acc[4])[2]), var)
    fam = np.array([f.family if f is not None else "" for f in chosen], dtype=object)
    if not rows:
        e = Arrivals.empty(fs=fs, n_bursts=1, detector="matched")
        arrivals = Arrivals(
            e.onset, fs, e.sigma, e.snr_db, e.confidence, e.burst_onsets, "matched",
            np.zeros(0, dtype=int),
        )  # fmt: skip
        return ChannelFit(arrivals, fam, keys, shapes, spread)
    arr = np.array(rows, dtype=np.float64)
    onset = arr[:, 0]
    snr_db = 20.0 * np.log10(np.maximum(arr[:, 2], 1e-300))
    conf = np.minimum(arr[:, 3], 1.0)
    arrivals = Arrivals(
        onset, fs, arr[:, 1], snr_db, conf, onset[:, None].copy(), "matched",
        arr[:, 4].astype(int), flags,
    )  # fmt: skip
    return ChannelFit(arrivals, fam, keys, shapes, spread)


#: Stagger shapes ``nu / a^2`` of one transmitter's groups (receivers) disagree beyond
#: this many sigma plus ``SHAPE_SLACK`` (receivers of one type differ a little).
SHAPE_Z = 4.0
SHAPE_SLACK = 0.25


#: A receiver that chose the resonator is held at its transmitter's consensus shape only
#: when that shape is stagger-tuned at least this far (``Re nu / a^2``; a maximally flat
#: pair is -1, the bandpass elements of the checks fit -0.8 to -1.4): the consensus of
#: two receivers whose fits mimicked a room's reflections had +0.3 to +0.5 (a split in
#: damping), and holding the third receiver there moved it 5 mm (pyroomacoustics rooms,
#: tests/experiments/test_oneway_rooms.py).
HOLD_SPLIT = -0.5


def _agree(a, b) -> bool:
    """Whether two (theta, cov) stagger shapes agree within ``SHAPE_Z`` sigma + slack."""
    d = a[0][2:] - b[0][2:]
    c = a[1][2:, 2:] + b[1][2:, 2:]
    n = float(np.linalg.norm(d))
    if n <= SHAPE_SLACK:
        return True
    d = d * (1.0 - SHAPE_SLACK / n)
    try:
        return float(d @ np.linalg.solve(c, d)) <= SHAPE_Z**2
    except np.linalg.LinAlgError:
        return False


def check_shapes(fits: Sequence[ChannelFit]) -> list[dict]:
    """Per channel, the groups to refit because the receivers disagree on the shape.

    The split ``nu / a^2`` of the stagger model belongs to the transducers: a transmitter
    heard by several receivers (of one type) gives one shape in all of them. A room's dense
    early reflections can be mimicked by the stagger's longer response too, but they differ
    from receiver to receiver, and a four-parameter fit may settle in a wrong optimum in
    one receiver. Per group label (transmitter), the receivers whose shapes agree
    (``SHAPE_Z`` sigma plus ``SHAPE_SLACK``) with the median shape are the consensus:

    * a majority (at least two) agree: each receiver that disagrees, and each receiver
      that chose the resonator for that transmitter, is refitted with the stagger model
      held at the consensus (``("stagger", theta)``): a receiver whose resonator fit won
      the model comparison (close at 10 dB: the four-parameter fit costs precision) but
      hears the transducer the others fit a shape for is timed late by the models'
      difference (bandpass elements of Q 12 at 10 dB: +35-46 mm in all ten windows of 2 of
      30 receivers, at a sigma of 11-30 mm; held at the consensus, within 2 sigma) when
      the consensus is stagger-tuned (``HOLD_SPLIT``);
    * no majority: every receiver that chose the stagger model is refitted with the
      resonator (``"resonator"``), with the model-choice variance of an undecided choice.

    Returns one ``force`` dict (:func:`fit_channel`) per channel (empty: keep the fit).
    """
    out: list[dict] = [{} for _ in fits]
    labels = {k for f in fits for k in f.shapes}
    for k in labels:
        chans = [c for c, f in enumerate(fits) if k in f.shapes]
        if len(chans) < 2:
            continue
        sh = [fits[c].shapes[k] for c in chans]
        med = (np.median([t for t, _ in sh], axis=0), np.median([c for _, c in sh], axis=0))
        ok = [_agree(x, med) for x in sh]
        resonator = [c for c, f in enumerate(fits) if k not in f.shapes and k in f.group]
        if not resonator and all(ok) and all(_agree(a, b) for a in sh for b in sh):
            continue
        if sum(ok) >= 2 and sum(ok) > len(sh) / 2:
            good = [x for x, o in zip(sh, ok, strict=True) if o]
            info = sum(np.linalg.inv(c) for _, c in good)
            theta = np.linalg.solve(info, sum(np.linalg.inv(c) @ t for t, c in good))
            for c, o in zip(chans, ok, strict=True):
                if not o:
                    out[c][k] = ("stagger", theta)
            if theta[2] <= HOLD_SPLIT:  # a transducer's shape, not mimicked multipath
                for c in resonator:
                    out[c][k] = ("stagger", theta)
        else:
            for c in chans:
                out[c][k] = "resonator"
    return out


#: The stagger split ``Re nu / a^2`` of a maximally flat pair (a 4th-order Butterworth
#: element; the in-model transducers of the checks fit -0.96 to -1.04 at 20 dB).
FLAT_SPLIT = -1.0
#: The split's sigma from the fits' information, times this: the groups' estimates
#: scatter about twice as widely as it says (measured, 10 dB, in-model transducers).
SPLIT_SIGMA_SCALE = 2.0
#: The order term enters from ``ORDER_Z[0]`` to fully at ``ORDER_Z[1]`` sigma of the
#: split beyond ``FLAT_SPLIT``.
ORDER_Z = (2.0, 4.0)
#: What the next model order moves the onset by, in units of the two fitted models'
#: difference ``d``: once from the stagger model's onset, twice from the resonator's
#: (measured on 6th-order Butterworth elements: 0.6-1.0 d beyond the stagger's onset).
ORDER_STEPS = {"stagger": 1.0, "resonator": 2.0}


def order_terms(fits: Sequence[ChannelFit]) -> list[dict]:
    """Per channel, the variance of the transducer model's order (samples^2) per group.

    The stagger model holds every element of two pole pairs, whatever its split. A
    transducer of higher order (a 6th-order band-pass, three pole pairs per element) is
    fitted as well, to within the noise at 10-20 dB (a misfit of 0.1-0.4 % of its energy,
    noiseless), but with its onset late by about the models' difference ``d`` (the
    stagger's onset minus the resonator's): 12-50 mm at Q 4-20. The out-of-band
    part of the response that sets the onset is not in the data, so no residual test
    sees it (``docs/theory/ultrasonic.md``, "beyond the second model"). What the fits do
    show is the split: a band flatter than a maximally flat pair's (``Re nu / a^2`` below
    ``FLAT_SPLIT``: -1.3 to -2.5 fitted for a 6th-order Butterworth) is what a
    two-pole-pair element gives only with a double-humped response and a higher-order one
    gives always. Per transmitter (group label) the receivers' splits are pooled
    (inverse-variance, the variance scaled by ``SPLIT_SIGMA_SCALE``; ``z`` the larger of
    the pooled split's and any one receiver's distance below ``FLAT_SPLIT`` in its
    sigma, since receivers that disagree can hide a wide split in the pool); at ``z``
    sigma below ``FLAT_SPLIT`` the weight ``r`` rises from 0 at ``ORDER_Z[0]`` to 1 at
    ``ORDER_Z[1]``, and each arrival of that transmitter gets the variance ``r (k d)^2``,
    ``k`` from :data:`ORDER_STEPS` by the model that timed it (the next order's step,
    Richardson's estimate of a truncation error from the last step). It is a transducer
    term: the same for every arrival through the same pair, absorbed by a calibration.

    Returns one dict per channel: group label -> ``(r, d2)``.
    """
    out: list[dict] = [{} for _ in fits]
    labels = {k for f in fits for k in f.spread}
    for k in labels:
        chans = [c for c, f in enumerate(fits) if k in f.spread]
        w = np.array([1.0 / (SPLIT_SIGMA_SCALE**2 * fits[c].spread[k][2]) for c in chans])
        s = np.array([fits[c].spread[k][1] for c in chans])
        ok = np.isfinite(w) & (w > 0) & np.isfinite(s)
        if not ok.any():
            continue
        split = float(np.sum(w[ok] * s[ok]) / np.sum(w[ok]))
        z = (FLAT_SPLIT - split) * math.sqrt(float(np.sum(w[ok])))
        # Receivers that disagree (a room's reflections, a fit astray) may hide a wide
        # split in the pooled one: any single receiver's own evidence counts too.
        z = max(z, float(np.max((FLAT_SPLIT - s[ok]) * np.sqrt(w[ok]))))
        r = min(max((z - ORDER_Z[0]) / (ORDER_Z[1] - ORDER_Z[0]), 0.0), 1.0)
        if r > 0.0:
            for c in chans:
                out[c][k] = (r, fits[c].spread[k][0])
    return out


def with_order_terms(fit: ChannelFit, terms: dict) -> Arrivals:
    """``fit``'s arrivals with the model-order variance of :func:`order_terms` (one
    channel's dict) added to ``sigma`` and to ``sigma_transducer``."""
    a = fit.arrivals
    if not terms or not len(a):
        return a
    var = np.zeros(len(a))
    for i, (key, fam) in enumerate(zip(fit.group, fit.family, strict=True)):
        t = terms.get(key)
        if t is not None and fam in ORDER_STEPS:
            var[i] = t[0] * ORDER_STEPS[fam] ** 2 * t[1]
    st = np.sqrt(a.sigma_transducer**2 + var)
    return replace(a, sigma=np.sqrt(a.sigma**2 + var), sigma_transducer=st)


def transducer_models(burst, *, fs: float, transducers: Sequence) -> tuple[tuple, float]:
    """The fit's models for ``burst`` through ``transducers`` and its starting Q.

    ``(ResonatorModel, StaggerModel)`` with ``stages`` the number of transducers given
    (None ones left out) and ``f0`` their mean resonance, and the geometric mean of their
    Q as the fit's start; ``((), 4.0)`` when none is given (nothing to fit).
    """
    from rangekit.detect.pathfit import ResonatorModel
    from rangekit.detect.stagger import StaggerModel

    ts = [t for t in transducers if t is not None]
    if not ts:
        return (), 4.0
    f0 = sum(t.f0_hz for t in ts) / len(ts)
    q0 = math.exp(sum(math.log(t.q) for t in ts) / len(ts))
    kw = {"fs": fs, "f0_hz": f0, "stages": len(ts)}
    return (ResonatorModel.for_burst(burst, **kw), StaggerModel.for_burst(burst, **kw)), q0


def detect_coded(
    x: np.ndarray,
    *,
    fs: float,
    burst=None,
    tx=None,
    rx=None,
    windows: np.ndarray | None = None,
    search: tuple[int, int] | None = None,
    **kw,
) -> Arrivals:
    """First paths of a coded burst in one channel, timed as :func:`rangekit.ranging.
    oneway.range_oneway` times them (``rangekit.detect.detect(..., method="fitted")``).

    The template is the drive through ``tx`` and ``rx`` (default rangekit's resonator,
    Q 4, at both ends; only the fit's starting point), the arrivals are timed by
    :func:`fit_channel` with both transducer models and carry the model-order term of
    :func:`order_terms` of this one channel. ``windows``, ``search`` and ``**kw`` as
    :func:`fit_channel` (``windows``: one arrival per window; default the whole channel).
    """
    from rangekit.detect.matched import coded_template
    from rangekit.signals.barker import CodedBurst
    from rangekit.signals.transducer import Transducer

    burst = CodedBurst() if burst is None else burst
    tx = Transducer() if tx is None else tx
    rx = Transducer() if rx is None else rx
    models, q0 = transducer_models(burst, fs=fs, transducers=(tx, rx))
    template = coded_template(burst, fs=fs, tx=tx, rx=rx)
    cf = fit_channel(
        x, fs=fs, template=template, models=models, windows=windows, search=search,
        q0=kw.pop("q0", q0), **kw,
    )  # fmt: skip
    return with_order_terms(cf, order_terms([cf])[0])
