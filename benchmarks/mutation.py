"""Mutation check: do a module's own tests notice when its code is changed?

For a module of :data:`TESTS` the script lists every mutation site of its source (AST):

* comparisons: ``<`` <-> ``<=``, ``>`` <-> ``>=``, ``==`` <-> ``!=``, ``is`` <-> ``is not``,
  ``in`` <-> ``not in`` (one operator of a chained comparison at a time);
* signs: binary ``+`` <-> ``-``, ``*`` <-> ``/``, unary ``-x`` -> ``x``;
* constants: an integer ``n`` -> ``n + 1``, a float ``0.0`` -> ``1.0`` and ``x`` -> ``2 x``,
  ``True`` <-> ``False``.

Docstrings, type annotations and ``__all__`` are not mutated. A seeded sample of the sites
(``--n``, default 40 per module, ``--seed``) is applied one at a time to a private copy of
the repository (``rangekit/``, ``cli/`` as ``rangekit_cli``, ``tests/``,
``pyproject.toml``, ``fixtures_audio/`` in a temporary folder that comes first on
``PYTHONPATH``; the working tree is never written), and the module's own tests
(:data:`TESTS`, with the module's doctests) run with ``pytest -x -q`` under a per-mutant
timeout. A mutant is *killed* when the tests fail, error or time out, and *survives* when
they pass; the score is killed / sampled. An unmutated baseline run must pass first.
Survivors are printed with their line, so a blind test can be written against each (some
survivors are equivalent mutants: the changed code computes the same result, e.g. a ``<``
vs ``<=`` on a float that is never equal).

Survivors judged equivalent mutants are listed in :data:`EQUIVALENT` (by the text of their
line, with the reason); the summary counts them apart as well ("without them": killed over
the sample less those), and marks them in the survivor list.

Not part of CI: it runs the tests once per mutant (minutes per module). Run it niced on
shared machines::

    nice -n 10 python benchmarks/mutation.py rangekit/ranging/beepbeep.py --n 40 --seed 0

With no module, every module of :data:`TESTS` is checked. The last line of each module is
an ``@row`` (``benchmarks/_report.py``) with the score; ``--json FILE`` writes every
mutant's outcome, and ``--rerun FILE`` runs only that file's survivors (whose source site
is unchanged) against the tests as they are now. The numbers are in ``docs/evidence.md``.

A package's score (issue 21 asks for ``rangekit/detect`` and ``rangekit/ranging``):
``--pooled N`` with a folder draws ``N`` sites from the union of the sites of its modules
that have a :data:`TESTS` entry, so each module weighs by its number of sites; each mutant
runs against its own module's tests, and the pooled score is printed beside the
per-module counts, with the modules of the folder that have no entry (and their sites)
named, since they are outside the score::

    nice -n 10 python benchmarks/mutation.py rangekit/ranging --pooled 60 --seed 100
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _report import row

#: Module -> its own tests (the module's doctests are added to these).
TESTS: dict[str, tuple[str, ...]] = {
    "rangekit/ranging/beepbeep.py": (
        "tests/ranging/test_beepbeep.py",
        "tests/ranging/test_beepbeep_boundaries.py",
        "tests/ranging/test_beepbeep_mutation.py",
    ),
    "rangekit/detect/refine.py": (
        "tests/detect/test_refine.py",
        "tests/detect/test_edge_kernels.py",
        "tests/detect/test_refine_boundaries.py",
        "tests/detect/test_refine_mutation.py",
    ),
    "rangekit/detect/changepoint.py": (
        "tests/detect/test_changepoint.py",
        "tests/detect/test_changepoint_mutation.py",
        "tests/detect/test_changepoint_mutation2.py",
        "tests/detect/test_precursor.py",
        "tests/detect/test_edge_kernels.py",
        "tests/detect/test_combine_drift.py",
        "tests/detect/test_changepoint_mutation3.py",
        "tests/detect/test_changepoint_mutation4.py",
        "tests/detect/test_changepoint_mutation5.py",
        "tests/detect/test_changepoint_sweeps.py",
        "tests/detect/test_quiet_level.py",
    ),
    "rangekit/detect/_kernels.py": ("tests/detect/test_kernels.py",),
    "rangekit/detect/condition.py": (
        "tests/detect/test_condition.py",
        "tests/detect/test_condition_mutation.py",
        "tests/detect/test_quiet_level.py",
    ),
    "rangekit/detect/matched.py": (
        "tests/detect/test_matched_fast.py",
        "tests/detect/test_matched.py",
        "tests/detect/test_mutation_matched.py",
        "tests/detect/test_matched_mutation2.py",
        "tests/ranging/test_ultrasonic_silence.py",
    ),
    "rangekit/detect/xcorr.py": (
        "tests/detect/test_xcorr_mutation.py",
        "tests/detect/test_front.py",
        "tests/detect/test_changepoint.py",
        "tests/detect/test_pooled_survivors.py",
    ),
    "rangekit/ranging/clock.py": (
        "tests/ranging/test_clock.py",
        "tests/ranging/test_clock_mutation.py",
    ),
    "rangekit/ranging/config.py": ("tests/ranging/test_config.py",),
    "rangekit/ranging/pipeline.py": ("tests/ranging/test_pipeline.py",),
    "rangekit/ranging/series.py": ("tests/ranging/test_series_fast.py",),
    "rangekit/ranging/run.py": ("tests/ranging/test_run.py", "tests/cli/test_range_library.py"),
    "rangekit/physics.py": ("tests/test_mutation_physics.py",),
    "rangekit/ranging/calibration.py": (
        "tests/ranging/test_calibration_mutation.py",
        "tests/cli/test_calibrate_cli.py",
    ),
    "rangekit/localize/ekf.py": (
        "tests/localize/test_ekf.py",
        "tests/localize/test_ekf_mutation.py",
    ),
    "rangekit/detect/stagger.py": (
        "tests/detect/test_stagger.py",
        "tests/detect/test_stagger_mutation.py",
        "tests/detect/test_pooled_survivors.py",
    ),
    "rangekit/detect/pathfit.py": (
        "tests/detect/test_pathfit.py",
        "tests/detect/test_pathfit_mutation.py",
        "tests/detect/test_pathfit_mutation2.py",
    ),
    "rangekit/detect/fitted.py": (
        "tests/detect/test_stagger.py",
        "tests/ranging/test_oneway_mutation.py",
        "tests/ranging/test_tof_mutation.py",
        "tests/detect/test_fitted_mutation.py",
        "tests/detect/test_pooled_survivors.py",
        "tests/ranging/test_ultrasonic_silence.py",
    ),
    "rangekit/detect/_pathfit_kernels.py": (
        "tests/detect/test_pathfit_kernels.py",
        "tests/detect/test_pathfit_kernels_mutation.py",
    ),
    "rangekit/detect/template.py": (
        "tests/detect/test_template.py",
        "tests/detect/test_template_coherent.py",
        "tests/detect/test_template_weighting.py",
        "tests/detect/test_template_transducer.py",
        "tests/detect/test_template_ultrasonic.py",
        "tests/detect/test_template_wrong.py",
        "tests/detect/test_template_mutation.py",
        "tests/detect/test_template_mutation2.py",
        "tests/detect/test_quiet_level.py",
    ),
    "rangekit/detect/_edge_kernels.py": (
        "tests/detect/test_edge_kernels.py",
        "tests/detect/test_combine_drift.py",
        "tests/detect/test_edge_kernels_mutation.py",
        "tests/detect/test_edge_kernels_mutation2.py",
    ),
    "rangekit/detect/__init__.py": ("tests/detect/test_front.py",),
    "rangekit/detect/files.py": (
        "tests/detect/test_detect_files.py",
        "tests/cli/test_detect_library.py",
    ),
    "rangekit/detect/_fft.py": ("tests/detect/test_pathfit.py",),
    "rangekit/detect/_kernel_choice.py": ("tests/detect/test_pathfit_kernels.py",),
    "rangekit/ranging/ultrasonic_setup.py": (
        "tests/ranging/test_ultrasonic_setup.py",
        "tests/cli/test_ultrasonic_setup_cli.py",
    ),
    "rangekit/detect/_coherent.py": (
        "tests/detect/test_template_coherent.py",
        "tests/detect/test_coherent_mutation.py",
        "tests/detect/test_coherent_mutation2.py",
    ),
    "rangekit/ranging/tof.py": (
        "tests/ranging/test_ultrasonic.py",
        "tests/ranging/test_tof_mutation.py",
    ),
    "rangekit/ranging/oneway.py": (
        "tests/ranging/test_ultrasonic.py",
        "tests/ranging/test_oneway_mutation.py",
    ),
    "rangekit/ranging/echo.py": (
        "tests/ranging/test_ultrasonic.py",
        "tests/ranging/test_echo_mutation.py",
    ),
    "rangekit/ranging/ultrasonic.py": (
        "tests/ranging/test_ultrasonic.py",
        "tests/cli/test_ultrasonic_cli.py",
        "tests/ranging/test_ultrasonic_mutation.py",
    ),
}

#: Survivors judged equivalent mutants (the changed code gives the same result on every
#: input the module can reach), per module: (the site's source line, stripped; the
#: mutation) -> why. Keyed by the line's text, not its number, so an entry outlives edits
#: elsewhere in the file and lapses when its line changes. Where a line has the same
#: mutation at several places, a third element picks one: its index among them, left to
#: right (:func:`site_key`). The summary reports the score with these set apart beside the
#: plain score (which counts them as survivors).
EQUIVALENT: dict[str, dict[tuple, str]] = {
    "rangekit/detect/changepoint.py": {
        ('joint = np.where(count >= min_bursts, joint, 0.0)', '0.0 -> 1.0'):
            '1 is far under f_joint (>= 12): the same local maxima above it',
        ('f_joint = 0.8 * f_min * min_bursts', '* -> /', 0):
            (
                'the joint is 0 or >= min_bursts f_min: any f_joint in (0, min_bursts f_min] '
                'picks the same edges'
            ),
        ('f_joint = 0.8 * f_min * min_bursts', '* -> /', 1):
            (
                'the joint is 0 or >= min_bursts f_min: any f_joint in (0, min_bursts f_min] '
                'picks the same edges'
            ),
        ('margin = int(math.ceil(48 * fs / 44100.0 + beep.taper_s * fs)) + 8', '8 -> 9'):
            (
                'one more sample of filter context (78 > post + 4 already): the segment equals '
                'the whole-recording cut (tested)'
            ),
        ("return float(percentile(sel, 10.0)) if len(sel) else 0.0", "0.0 -> 1.0"):
            "sel is empty only with no frame at all: no arrival reads quiet",
        ('if far > 0 and float(run.max()) > 10 ** (PRE_RISE_DB / 10) * far:', '> -> >=', 1):
            'a float tie, never met',
        ('tw = min(1500.0, 0.5 * lo, max(nyq - hi, 0.01 * nyq))', '0.01 -> 0.02'):
            "the band's top leaves nyq - hi >= 0.02 nyq, so the max is the same",
        (
            'sg = np.clip(np.nan_to_num(raw_sg, nan=1e6, posinf=1e6), 1e-3, 1e6)',
            '1000000.0 -> 2000000.0',
            0,
        ):
            'the clip right after takes 2e6 back to 1e6',
        (
            'sg = np.clip(np.nan_to_num(raw_sg, nan=1e6, posinf=1e6), 1e-3, 1e6)',
            '1000000.0 -> 2000000.0',
            1,
        ):
            'the clip right after takes 2e6 back to 1e6',
        ('if cond.taps is None or len(x) == 0:', '0 -> 1'):
            'a one-sample recording has no arrival: its out-of-band verdict is never read',
        ("if len(e) >= _edge_kernels.NUMBA_MIN_SAMPLES // hop or long_recording():", ">= -> >"):
            'at exactly that length the compiled and numpy paths give the same frames (tested)',
        ('for a, b in zip(starts.tolist(), ends.tolist(), strict=True):', 'True -> False'):
            'the two lists always have equal length',
        ("tw = min(1500.0, 0.5 * lo, max(nyq - hi, 0.01 * nyq))", "* -> /", 1):
            "hi <= 0.98 nyq, so nyq - hi >= 0.02 nyq exceeds 0.01 nyq and 0.01 / nyq: the max",
        ("compiled = len(x) >= _edge_kernels.NUMBA_MIN_SAMPLES or long_recording()", ">= -> >"):
            "which path at exactly NUMBA_MIN_SAMPLES: both give the same numbers (tested equal)",
        ("if lv is None or ref is None or not max(lv) >= MASK_RATIO * ref[0]:", ">= -> >"):
            "a tie of two mean band energies (floats) at exactly MASK_RATIO, never met",
        ("out = np.zeros((n_a + 1, 7))", "1 -> 2"):
            "one row per anchor at most and rows read up to n_rows: a spare row, never read",
        ("a = a.astype(np.float64, copy=False)  # short: the numpy path, in float64",
         "False -> True"): "a copy of the same values: the detection reads the same numbers",
        ("if end - 2 * near < 0 or last - n_last + 1 < 0 or last >= len(e):", "< -> <=", 1):
            "at last = n_last - 1 (7 frames) end <= last + 1 < 2 near (68): skipped already",
        ("w_all = 1.0 / sg**2", "1.0 -> 2.0"):
            "a common factor of the support weights: it cancels in their weighted means",
        ("if snr < LOW_SNR_DB:", "< -> <="): "a median SNR (float) of exactly 10 dB, never met",
        ("return [r for r, k in zip(rows, keep, strict=True) if k]", "True -> False"):
            "keep is built with one entry per row: strict never raises",
        ("half = (len(cond.taps) - 1) // 2 if cond.taps is not None else 0", "0 -> 1"):
            "without taps the compiled loop reads no half (no band-limiting)",
        ("if expected is not None and len(arr) > expected:", "> -> >="):
            "at len(arr) == expected the trim drops order[:0], none: take(arange(n)) is arr",
        # Seed 8 (judged after the draw, docs/evidence.md sixth round):
        ("@dataclass(frozen=True)", "True -> False"):
            "the private _Conditioner is never assigned to (BurstCandidates' frozenness is "
            "tested, so its own mutant is killed, not listed)",
        ("if fit is not None and fit.f_stat >= F_MIN * cond.f_scale:", ">= -> >"):
            "a tie of a float edge statistic with the threshold, never met",
        ("sg = np.clip(np.nan_to_num(raw_sg, nan=1e6, posinf=1e6), 1e-3, 1e6)",
         "1000000.0 -> 2000000.0", 2):
            "the clip's upper 1e6: nan_to_num caps failed fits at 1e6 already; only a finite "
            "sigma above 1e6 differs, weighing 1e-12 or less either way",
        ("n_rows = np.zeros(1, dtype=np.int64)", "1 -> 2"):
            "a one-element counter: the kernel and the loop read and write n_rows[0] only",
        # Seeds 9 and 10 (judged after the draws, docs/evidence.md seventh round):
        ("while i < n_a:", "< -> <="):
            "at i == n_a the kernel starts past the last anchor: no anchor done, no row, and "
            "the loop breaks (i >= n_a)",
        ("if joint[u] < f_joint or not sep <= u < width - sep:", "< -> <=", 1):
            "u >= width - sep with joint[u] >= f_joint returned (re-anchored) just before; "
            "else joint[u] < f_joint holds: None either way",
        ("if i < j and keep[i] and keep[j] and (i, j) in alias:", "< -> <="):
            "(i, i) is never in alias (pairs are stored lo < hi): i == j does nothing",
        ("if end - 2 * near < 0 or last - n_last + 1 < 0 or last >= len(e):", "0 -> 1", 1):
            "the clause is implied by the first: end >= 2 near (68) puts last >= end - 1 "
            ">= n_last (8), so last - n_last + 1 >= 60",
    },
    "rangekit/detect/condition.py": {
        ("top = float(np.max(e)) if n else 0.0", "0.0 -> 1.0"):
            "n > block >= 1 here (n <= block returned just before): the else is never taken",
        ("low_pass_only = False", "False -> True"): "only `width` reads it, `tw` either way",
        ("low_pass_only = lo - tw <= 0.0", "<= -> <"):
            "at lo == tw the branch sets tw = lo, the value it had",
        ("if k <= 1:", "<= -> <"): "k = 1 through the run loop gives the same copy of m",
        ("if atten_db > 21:", "> -> >="): "both branches give beta 0 at exactly 21 dB",
        ("if len(x) * len(h) > 1 << 20:", "> -> >="):
            "both convolution paths give the output to rounding (tested to 1e-9)",
        ("if len(x) * len(h) > 1 << 20:", "* -> /"):
            "which convolution path runs: both give the output to rounding",
        ("if b < n_full and all_live[b] and block >= 8:", ">= -> >"):
            "a block of 8 one at a time gives the vectorised level (tested equal)",
        ("if len(h) == 1:", "1 -> 2"): "one tap through np.convolve is the same h[0] * x",
        ("if x.dtype not in (np.float32, np.float64):", "not in -> in"):
            "the same mask (float32 thresholds compare as float64 ones); only a copy saved",
    },
    "rangekit/detect/matched.py": {
        ('if lo < 0 or hi > n:', '> -> >='):
            'at hi == n the right pad is empty: the same piece',
        ('keep = int(np.searchsorted(-e, -e[0] * 10.0 ** (-tail_db / 10.0)))', '0 -> 1'):
            'every coded drive starts at sin(0) = 0, so the filtered y[0] is 0 and e[1] == e[0]',
        ('n = max(1 << int(math.ceil(math.log2(n_in))), 4 * d)', '4 -> 5'):
            (
                'the second term is never taken: the shortest decimated FIR of 268 templates had '
                '53-107 taps for d = 2-8 (> 5 d)'
            ),
        (
            'if not 0.1 * noise * noise_scale <= sigma_fit <= 2.0 * noise * noise_scale:',
            '<= -> <',
            0,
        ):
            'a float tie of two noise levels, never met',
        (
            'if not 0.1 * noise * noise_scale <= sigma_fit <= 2.0 * noise * noise_scale:',
            '<= -> <',
            1,
        ):
            'a float tie of two noise levels, never met',
        ('if i1 - i0 < 3 or not 0 <= int(round(first)) < len(env):', '<= -> <'):
            (
                'round(first) == 0 makes i1 = floor(first) - reach <= 0 < i0 + 3: the first test '
                'returns already'
            ),
        ("sp = np.asarray(spans, dtype=np.int64).reshape(-1, 2)", "1 -> 2"):
            "numpy (2.4) reads any negative size as the unknown one: reshape(-2, 2) is (-1, 2)",
        ("live = e > rel_zero * float(e.max()) if e.max() > 0 else np.zeros(len(e), bool)",
         "> -> >=", 1): "at e.max() == 0 every e is 0: e > 0 is the same all-False mask",
        ("if s1 - s0 < 3 or b - a < 3:", "- -> +", 0):
            "a window under 3 samples has the empty span (s0, s0) (_window_spans): b - a < 3",
        ("b_hi = max(b_lo, min(n_blocks, (nx + lead - n) // step + 1)) if nx + lead >= n "
         "else b_lo", "+ -> -", 1):
            "fewer blocks as views of x: the rest are copied by padded(), the same samples",
        ("per = max(1, (1 << 18) // n)  # blocks per batched FFT call", "1 -> 2", 0):
            "batch size only: each row's transform does not depend on the batch",
        ("if lo < 0 or hi > n:", "0 -> 1"): "at lo == 0 the padding is empty: the same piece",
        ("sa_spec[f < 0] = 0.0", "< -> <="):
            "the DC bin adds a real constant to s_a; only its imaginary part (d_phi) is used",
        ("eps = max(f.misfit, 0.0) * (1.0 - MISFIT_Z_FREE / z) if z > MISFIT_Z_FREE else 0.0",
         "> -> >="): "at z == MISFIT_Z_FREE the factor 1 - 3 / z is 0: eps is 0 either way",
    },
    "rangekit/ranging/echo.py": {
        ("(None, 4.0)", "4.0 -> 8.0"): "the starting Q of a fit: with a probe there is no model",
    },
    "rangekit/ranging/oneway.py": {
        ("(None, 4.0) if probe is not None else _fit_model(burst, fs, (tx, rx), fit_transducers)",
         "4.0 -> 8.0"): "the starting Q of a fit: with a probe there is no model to start",
        ("return None, 4.0", "4.0 -> 8.0"): "the starting Q of a fit: without a model, unused",
        ("return (models if stagger else models[:1]), q0", "1 -> 2"):
            "no caller passes stagger=False (both take the default True)",
    },
    "rangekit/ranging/tof.py": {
        ("k = np.arange(int(math.floor(n_samples / per + 0.5)) + 1)", "1 -> 2"):
            "the extra start, round((K + 1) per) > n_samples + per / 2, is dropped (< n_samples)",
        ("starts = starts[starts < n_samples]", "< -> <="):
            "a window starting at the end has length 0 and fails the half-period test",
        ("pool: bool = True,", "True -> False"): "both callers (oneway, echo) pass pool",
        ("first_window: int = 0,", "0 -> 1"): "both callers pass first_window",
        ("q0: float = 4.0,", "4.0 -> 8.0"): "both callers pass q0",
        ("per_channel = [with_order_terms(f, t) for f, t in zip(cf, terms, strict=True)]",
         "True -> False"): "order_terms gives one term per channel: strict never raises",
        ("found = dict(zip(arr.window.tolist(), range(len(arr)), strict=True))",
         "True -> False"): "both have len(arr) items: strict never raises",
    },
    "rangekit/detect/fitted.py": {
        ("acc[3] = fit.theta_hat", "3 -> 4"):
            "never reached: each counted info is S / sigma^2 (S a Schur complement of a Gram "
            "matrix) with det > 0, so positive definite, and so is their sum: solve never raises",
        ("if fs_ is not None and fs_.n0 == fr.n0 and fr.snr >= low:", ">= -> >"):
            "a tie of a fit's SNR (float) with the low-SNR level, never met",
        ("for got, key in zip(fits, keys, strict=True):", "True -> False"):
            "fits and keys are appended together, one per row: strict never raises",
        ("for i, (k, f) in enumerate(zip(keys, chosen, strict=True)):", "True -> False"):
            "chosen is built one per entry of fits, as long as keys: strict never raises",
        ("for i, (k, f) in enumerate(zip(keys, chosen, strict=True))", "True -> False"):
            "chosen is built one per entry of fits, as long as keys: strict never raises",
        ("for i, f in zip(idx, pooled, strict=True):", "True -> False"):
            "pool_fits returns one fit per fit given: strict never raises",
        ("good = [x for x, o in zip(sh, ok, strict=True) if o]", "True -> False"):
            "ok is built one per shape of sh: strict never raises",
        ("for c, o in zip(chans, ok, strict=True):", "True -> False"):
            "sh (and so ok) is built one per channel of chans: strict never raises",
        ("for i, (key, fam) in enumerate(zip(fit.group, fit.family, strict=True)):",
         "True -> False"): "fit_channel's ChannelFit has one group label and one family per "
            "arrival (keys and chosen): strict never raises",
        ("self.w = 1.0", "1.0 -> 2.0"):
            "never read: every group is decided (decide sets w) before the sigma loop reads it",
        ("windows = np.asarray(windows, dtype=np.int64).reshape(-1, 2)", "1 -> 2"):
            "numpy (2.4) reads any negative size as the unknown one: reshape(-2, 2) is (-1, 2)",
        ("if k == key and f is not None and f.family == fam", "== -> !=", 1):
            "the loop's two passes swap the two families' (disjoint) sets: the same sets pooled",
    },
    "rangekit/detect/_coherent.py": {
        ('a = max(0, j - SINC_HALF - 2)', '2 -> 3'):
            (
                'one sample more before the taps read (floor(lag) - 15 .. + 16), which lie inside'
                ' either way'
            ),
        ("while b - a > 1e-4:", "> -> >="): "the interval, 2 g^k wide, is never exactly 1e-4",
        ("if f1 >= f2:", ">= -> >"):
            "at a tie the extremum lies between x1 and x2, which either branch keeps",
        ("pk = np.flatnonzero((mid >= r[:-2]) & (mid > r[2:])) + 1", "> -> >="):
            "a plateau counted twice: lag 0 of a self response is a strict maximum, so the "
            "largest side value v[1] is the same",
        ("lo, hi = max(1, j - reach), min(len(c) - 1, j + reach + 1)", "- -> +", 1):
            "the slice c.real[lo - 1 : hi + 1] stops at len(c) either way",
        ("t = a + refine_extremum(np.ascontiguousarray(c.real[a : p + SINC_HALF + 3]), p - a)",
         "3 -> 4"): "a sample no tap reads: [p - 1, p + 1] reads up to p + 17 < p + 19",
    },
    "rangekit/detect/pathfit.py": {
        ('best = (-1.0, 0, thetas[0])', '1.0 -> 2.0'):
            'the score p is never negative: it beats -1 and -2 alike',
        ("return _POCKET.r2c(buf, (0,), True, 0, None, 1)", "1 -> 2"):
            "pocketfft's thread count: one 1-d transform is done by one thread either way, "
            "bit-identical",
        ("if a.ndim and axis in (-1, a.ndim - 1) and a.shape[-1] <= n and _POCKET is not None:",
         "-x -> x", 0): "scipy.fft.ifft instead: the same pocketfft call, bit-identical",
        ("if a.ndim and axis in (-1, a.ndim - 1) and a.shape[-1] <= n and _POCKET is not None:",
         "1 -> 2", 1): "scipy.fft.ifft instead: the same pocketfft call, bit-identical",
        ("if a.ndim and axis in (-1, a.ndim - 1) and a.shape[-1] <= n and _POCKET is not None:",
         "is not -> is"): "scipy.fft.ifft instead: the same pocketfft call, bit-identical",
        ("return 1 << max(4, int(math.ceil(math.log2(max(n, 1)))))", "1 -> 2", 1):
            "the grid size n is always above 2",
        ("return USE_KERNEL and _KERNEL.get() and x.dtype == np.float64 and x.flags.c_contiguous",
         "== -> !="):
            "the numpy reference instead of the compiled step: equal to 1e-15 "
            "(test_pathfit_kernels.py)",
        ("if nb > 2:", "> -> >="): "at nb == 2 the theta block has no columns: an empty assignment",
        ("for attempt in range(2):", "2 -> 3"): "the look-earlier branch needs attempt == 0",
        ("j_max = max(1, len(seg) - len(model.drive) // 2)", "1 -> 2"):
            "fit_arrival refuses a segment shorter than the drive: the difference is >= 50",
        ("pv = np.where(ok, 2.0 * num / np.maximum(den, 1e-300)[:, None], -1.0)", "1.0 -> 2.0"):
            "valid pairs explain a non-negative energy and win; the fill value is not used",
        ("if math.sqrt(max(p, 0.0)) / sigma < k_add:", "< -> <="):
            "a tie of a float statistic with k_add, never met",
        ("misfit = (st.cost - dof * sigma**2) / sig_energy if sig_energy > 0 else 0.0",
         "> -> >="): "a fit above k_add noise scales has a nonzero signal energy",
        ("mean = theta[0]", "0 -> 1"): "overwritten by the loop's first pass before any use",
        ("half = np.flatnonzero(r[: model.n_fft // 2] < 0.5 * r[0])", "< -> <="):
            "an envelope exactly half its peak at an integer lag, never met",
        ("if u_min < 0.25 * model.pre and n0 > 0 and attempt == 0 and start is None:",
         "> -> >="): "at n0 == 0 the second pass reads the same segment (n0 stays 0): the same fit",
        ("if inside[i] and u_abs[i] < u_abs[strongest] and snr[i] >= k_noise:", "< -> <="):
            "the onsets are distinct: only the strongest itself is added, which is the default",
        ("if inside[i] and u_abs[i] < u_abs[strongest] and snr[i] >= k_noise:", ">= -> >"):
            "a tie of a path's SNR with k_noise, never met",
        ("small = np.all(np.abs(accepted.u - st.u) < 1e-4) and np.all(", "< -> <="):
            "an onset step of exactly 1e-4 samples, never met",
        ("st.cost - two.cost > k_add**2 * sigma**2", "> -> >="):
            "a tie of the two-path gain with k_add^2 noise variances, never met",
        ("np.abs(theta_hat - theta_lin) > 3.0 * model.theta_step()", "> -> >="):
            "a Newton step of exactly 3 step limits, never met",
        ("n_par: int = 0", "0 -> 1"):
            "a default never read: the one PathFit constructor call (_summarize) passes n_par",
        ("if a.ndim == 1 and len(a) <= n and a.dtype == np.float64 and _POCKET is not None:",
         "== -> !=", 0): "scipy.fft.rfft instead (every caller passes 1-d): the same pocketfft "
            "call, bit-identical (checked)",
        ("if a.ndim == 1 and len(a) <= n and a.dtype == np.float64 and _POCKET is not None:",
         "1 -> 2"): "scipy.fft.rfft instead: the same pocketfft call, bit-identical (checked)",
        ("if len(self._cache) > 64:", "64 -> 65"): "a cache's size: the same spectra",
        ("@functools.lru_cache(maxsize=16)", "16 -> 17"): "a cache's size: the same models",
        ("return _ifft(buf, n=buf.shape[-1], axis=-1)", "1 -> 2", 0):
            "a branch for another scipy layout (_POCKET None), never taken with this scipy",
        ("return _ifft(buf, n=buf.shape[-1], axis=-1)", "1 -> 2", 1):
            "a branch for another scipy layout (_POCKET None), never taken with this scipy",
        ("return _ifft(buf, n=buf.shape[-1], axis=-1)", "-x -> x", 0):
            "a branch for another scipy layout (_POCKET None), never taken with this scipy",
        ("return _ifft(buf, n=buf.shape[-1], axis=-1)", "-x -> x", 1):
            "a branch for another scipy layout (_POCKET None), never taken with this scipy",
        ("dof = max(1, len(st.r) - n_par)", "1 -> 2"):
            "the one caller passes n_par = 3 + n_theta; st.r is a segment, at least a drive long",
    },
    "rangekit/detect/refine.py": {
        ("q_base = np.linalg.qr(cols[:, 2:])[0] if cols.shape[1] > 2 else np.zeros((len(k), 0))",
         "0 -> 1", 1):
            "without nuisance columns a zero column: numpy reads no base then, the compiled "
            "statistic adds its zero row's 0 to the base energy",
    },
    "rangekit/detect/template.py": {
        ('s_crb = 1.0 / (2.0 * math.pi * wf.beta * snr) if snr > 0 else math.inf', '> -> >='):
            "snr is a chosen path's positive height over a positive floor (or inf): never 0",
        ('if ambiguous_near or (strongest and pk.height < AMBIGUOUS_MARGIN * thr):', '< -> <='):
            (
                'a float tie at exactly AMBIGUOUS_MARGIN thr, never met (the rule is tested at '
                '1.48 and 1.52)'
            ),
        ("a = np.array([r[:5] for r in rows], dtype=np.float64)", "5 -> 6"):
            "a sixth column (the flag bits, as floats) that is never read: only a[:, :5] are",
        ("q < p and env[p] < TAIL_MARGIN * _tail_level(decay, p) for q, decay in decays",
         "< -> <=", 0): "q is an accepted peak, p a candidate not within sep >= 1 of any: q != p",
        ("if not paths or m < 2 or j < 1 or j + 1 >= len(c):", "< -> <=", 0):
            "m = lookback + 256 lags >= 256 (_weighted): m < 2 and m <= 2 are both false",
        ("if not paths or m < 2 or j < 1 or j + 1 >= len(c):", "2 -> 3"):
            "m = lookback + 256 lags >= 256 (_weighted): m < 2 and m < 3 are both false",
        ("if spectra is not None and _coverage(xc, j, base, wf, spectra) < POOR_MATCH_COVERAGE:",
         "< -> <="):
            "a tie of the share-weighted coverage (a ratio of sums of float shares) with 0.5",
        ("@functools.lru_cache(maxsize=8)", "8 -> 9"):
            "the cache's size: the same _Base for a probe and rate, cached or rebuilt",
        ("while mid + k < len(env) and env[mid + k] > 0.25 * top:", "+ -> -", 0):
            "the self response's envelope falls below a quarter within its main lobe, long "
            "before the end: the bound is never what stops the loop",
        ("while mid + k < len(env) and env[mid + k] > 0.25 * top:", "+ -> -", 1):
            "the self response (an autocorrelation) is symmetric about mid: env[mid - k] "
            "equals env[mid + k]",
        ("return 1.0", "1.0 -> 2.0"):
            "_coverage's undecided value: its one caller only compares it with "
            "POOR_MATCH_COVERAGE (0.5), which 1 and 2 both clear",
        ("return float(strong.sum()) > LOWBAND_POWER_RATIO * float(N[inb].sum())", "> -> >="):
            "a tie of two float power sums (the band's positive), never met",
        ("shares = shares / max(float(shares.sum()), 1e-300)", "1e-300 -> 2e-300"):
            "the template's weighted PSD over its own band sums far above 1e-300: never the max",
        # Seed 1 (judged after the draw):
        ("if w < 1.0:", "< -> <="):
            "at w = 1 the envelope's share (1 - w) sqrt(eps) / (2 pi beta) adds exactly 0",
        ("s1 = min(max(j + len(base.template), 0), len(x))", "0 -> 1"):
            "a timed first path lies at most a few samples before sample 0 and the template "
            "is far longer: j + len(template) > 1, never clipped",
        ("pk = np.flatnonzero((seg >= env[a - 1 : b - 1]) & (seg > env[a + 1 : b + 1]))",
         "> -> >="): "a tie of two neighbouring envelope values (floats >= thr / 1.5), never met",
        ("a = np.where(tested, r / np.maximum(sh, 1e-300), 0.0)", "1e-300 -> 2e-300"):
            "tested sub-bands have sh >= 1 / 32; elsewhere np.where drops the quotient",
        ("@dataclass(frozen=True, eq=False)", "True -> False"):
            "the private _Base and _Filter are never assigned to (_Base's spectrum cache "
            "goes through object.__setattr__)",
    },
    "rangekit/detect/_edge_kernels.py": {
        ('n_in += 1', '1 -> 2'):
            (
                'every count doubles alike and is compared only with another count so made (top ='
                ' n_in); n_ok is counted apart'
            ),
    },
    "rangekit/detect/_pathfit_kernels.py": {
        ('while lam < 1e8:', '< -> <='):
            (
                'lam is 1e-3 times powers of 10 and of 1/3 (floored at 1e-9): never exactly 1e8 '
                'in floats'
            ),
        ('if lam < 1e8:', '< -> <='):
            (
                'lam is 1e-3 times powers of 10 and of 1/3 (floored at 1e-9): never exactly 1e8 '
                'in floats'
            ),
        ('e2 = np.empty((0, 0))', '0 -> 1', 0):
            'returned only with ok False, when the caller reads none of the arrays',
        ('e2 = np.empty((0, 0))', '0 -> 1', 1):
            'returned only with ok False, when the caller reads none of the arrays',
        ('first_s = 0', '0 -> 1'):
            'always overwritten: order is a permutation of range(k) and first is in it',
        ("e1 = np.empty(0)", "0 -> 1"):
            "returned only with ok False, on which the caller runs the numpy reference and "
            "reads none of the arrays",
    },
    "rangekit/detect/stagger.py": {
        ("if len(self._cache) > 64:", "64 -> 65"): "a cache's size: the same spectra",
    },
    "rangekit/physics.py": {
        ("c: float = field(init=False, repr=False, compare=False)", "False -> True", 2):
            "c is a function of the compared fields: the same equality and hash classes",
    },
    "rangekit/ranging/run.py": {
        ("return RangeRun(scheme, True, SERIES_FIELDS[scheme], meta, names[:1], rows, rows)",
         "1 -> 2"): "an ultrasonic series has exactly one file (checked before): [:2] is [:1]",
    },
    "rangekit/ranging/series.py": {
        ("if stop <= start:", "<= -> <"): "reading 0 frames gives the same empty block",
        ("ok = (starts < n_samples) & ((stops - starts) >= 0.5 * per)", "< -> <="):
            "a window starting at the end has length 0 and fails the half-period test",
        ("jobs: int = 1,", "1 -> 2"):
            "the series is the same for any jobs (test_parallel_jobs_give_the_same_series); "
            "only the worker count differs",
    },
    "rangekit/ranging/calibration.py": {
        ("if abs(cal.cov_speed_offset) > bound * (1 + 1e-9) + 1e-300:", "> -> >="):
            "a float tie: a covariance exactly at the allowance above the sigmas' product",
    },
    "rangekit/ranging/config.py": {
        ('if hasattr(sd, "tolist") and getattr(sd, "ndim", 0) > 0:  # a numpy array',
         "> -> >="): "a 0-d array and its float pass the same checks",
        ('if hasattr(sd, "tolist") and getattr(sd, "ndim", 0) > 0:  # a numpy array',
         "0 -> 1", 0): "only objects with tolist and no ndim (array.array), undocumented",
        ("self_distances(sd, 1)", "1 -> 2"): "one value broadcast to 2 passes the same checks",
    },
}  # fmt: skip

_CMP = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
}
_BIN = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult}
_SYM = {
    ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!=",
    ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in",
    ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/",
}  # fmt: skip


@dataclass(frozen=True)
class Site:
    """One mutation: replace source lines/columns [start, end) by ``new`` (0-based cols)."""

    line: int
    col: int
    end_line: int
    end_col: int
    new: str
    what: str


@dataclass
class Outcome:
    site: Site
    status: str  # "killed", "survived", "timeout", "invalid"
    seconds: float


def _skip_nodes(tree: ast.Module) -> set[int]:
    """ids of nodes not to mutate: docstrings, annotations, ``__all__``."""
    skip: set[int] = set()

    def mark(node):
        for n in ast.walk(node):
            skip.add(id(n))

    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(node, ast.Module | ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                mark(body[0])
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            args = node.args
            for a in [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]:
                if a is not None and a.annotation is not None:
                    mark(a.annotation)
            if node.returns is not None:
                mark(node.returns)
        if isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            mark(node)
        if isinstance(node, ast.JoinedStr):  # f-strings: messages, not logic
            mark(node)
    return skip


def _paren(node: ast.AST) -> str:
    return f"({ast.unparse(node)})"


def sites(source: str) -> list[Site]:
    """Every mutation site of ``source`` (module docstring's list), in source order."""
    tree = ast.parse(source)
    skip = _skip_nodes(tree)
    out: list[Site] = []

    def add(node, new, what):
        out.append(Site(node.lineno, node.col_offset, node.end_lineno, node.end_col_offset,
                        new, what))  # fmt: skip

    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Compare):
            for i, op in enumerate(node.ops):
                if type(op) in _CMP:
                    ops = list(node.ops)
                    ops[i] = _CMP[type(op)]()
                    new = ast.Compare(node.left, ops, node.comparators)
                    add(node, _paren(new), f"{_SYM[type(op)]} -> {_SYM[type(ops[i])]}")
        elif isinstance(node, ast.BinOp) and type(node.op) in _BIN:
            new = ast.BinOp(node.left, _BIN[type(node.op)](), node.right)
            add(node, _paren(new), f"{_SYM[type(node.op)]} -> {_SYM[type(new.op)]}")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            add(node, _paren(node.operand), "-x -> x")
        elif isinstance(node, ast.Constant) and type(node.value) in (bool, int, float):
            v = node.value
            if isinstance(v, bool):
                new = repr(not v)
            elif isinstance(v, int):
                new = repr(v + 1)
            else:
                new = "1.0" if v == 0.0 else repr(2.0 * v)
            add(node, new, f"{v!r} -> {new}")
    out.sort(key=lambda s: (s.line, s.col, s.what))
    return out


def apply(source: str, site: Site) -> str:
    """``source`` with one site replaced (positions as given by :mod:`ast`, in characters)."""
    lines = source.splitlines(keepends=True)
    start = sum(len(x) for x in lines[: site.line - 1]) + _chars(lines[site.line - 1], site.col)
    end = sum(len(x) for x in lines[: site.end_line - 1]) + _chars(
        lines[site.end_line - 1], site.end_col
    )
    return source[:start] + site.new + source[end:]


def _chars(line: str, byte_col: int) -> int:
    """AST column offsets count UTF-8 bytes; convert to characters."""
    return len(line.encode("utf-8")[:byte_col].decode("utf-8"))


def _copy_tree(dst: pathlib.Path) -> None:
    ignore = shutil.ignore_patterns(".hypothesis", ".pytest_cache", "*.pyc")
    shutil.copytree(ROOT / "rangekit", dst / "rangekit", ignore=ignore)  # keeps numba caches
    shutil.copytree(ROOT / "cli", dst / "rangekit_cli", ignore=ignore)
    shutil.copytree(ROOT / "tests", dst / "tests", ignore=ignore)
    shutil.copy2(ROOT / "pyproject.toml", dst / "pyproject.toml")
    shutil.copytree(ROOT / "fixtures_audio", dst / "fixtures_audio")  # the CLI tests' data


def _run_tests(work: pathlib.Path, args: list[str], timeout_s: float) -> tuple[str, float]:
    env = dict(os.environ, PYTHONPATH=str(work), PYTHONDONTWRITEBYTECODE="1")
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-n", "0", "-p", "no:cacheprovider", *args]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    try:
        rc = proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # this mutant's own process group only
        proc.wait()
        return "timeout", time.perf_counter() - t0
    return ("survived" if rc == 0 else "killed"), time.perf_counter() - t0


def check_module(
    module: str,
    *,
    n: int,
    seed: int,
    timeout_s: float,
    only: list[Site] | None = None,
    label: str = "re-run",
) -> list[Outcome]:
    """Sample ``n`` sites of ``module`` (seeded) and run its tests on each mutant.

    With ``only``, run exactly those sites (``--rerun``, or a pooled sample's share:
    ``label`` says which) instead of a sample.
    """
    tests = [t for t in TESTS[module] if (ROOT / t).exists()]
    source = (ROOT / module).read_text(encoding="utf-8")
    all_sites = sites(source)
    if only is None:
        rng = np.random.default_rng(seed)
        pick = sorted(rng.choice(len(all_sites), size=min(n, len(all_sites)), replace=False))
        sample = [all_sites[i] for i in pick]
        what = f"{len(sample)} sampled (seed {seed})"
    else:
        sample = only
        what = f"{len(sample)} {label}"
    print(f"{module}: {len(all_sites)} sites, {what}; tests: " + " ".join(tests), flush=True)
    with tempfile.TemporaryDirectory(prefix="rk-mutation-") as tmp:
        work = pathlib.Path(tmp)
        _copy_tree(work)
        target = work / ("rangekit_cli" + module[3:] if module.startswith("cli/") else module)
        args = [*tests, module]  # the module path runs its doctests (--doctest-modules)
        status, base_s = _run_tests(work, args, timeout_s=max(timeout_s, 600.0))
        if status != "survived":
            raise SystemExit(f"{module}: the unmutated tests do not pass ({status}); stopping")
        limit = max(timeout_s, 3.0 * base_s)
        print(f"  baseline passes in {base_s:.1f} s; per-mutant timeout {limit:.0f} s", flush=True)
        out = []
        for k, site in enumerate(sample, 1):
            text = apply(source, site)
            try:
                compile(text, module, "exec")
            except SyntaxError:
                out.append(Outcome(site, "invalid", 0.0))
                continue
            target.write_text(text, encoding="utf-8")
            status, sec = _run_tests(work, args, limit)
            out.append(Outcome(site, status, sec))
            print(f"  [{k:2d}/{len(sample)}] line {site.line:4d} {site.what:<22} {status} "
                  f"({sec:.1f} s)", flush=True)  # fmt: skip
        target.write_text(source, encoding="utf-8")
    return out


def site_key(site: Site, lines: list[str], all_sites: list[Site]) -> tuple:
    """``site``'s key in :data:`EQUIVALENT`: (its line's text, stripped; the mutation),
    with a third element, the site's index left to right among the line's sites of the same
    mutation, where the line has more than one."""
    same = [s for s in all_sites if s.line == site.line and s.what == site.what]
    key = (lines[site.line - 1].strip(), site.what)
    return key if len(same) < 2 else (*key, sorted(same, key=lambda s: s.col).index(site))


def summary(module: str, out: list[Outcome], n_sites: int, seed: int, rerun: bool = False) -> dict:
    valid = [o for o in out if o.status != "invalid"]
    killed = sum(o.status in ("killed", "timeout") for o in valid)
    score = killed / len(valid) if valid else float("nan")
    surv = [o.site for o in valid if o.status == "survived"]
    print(f"{module}: killed {killed}/{len(valid)} = {100 * score:.0f} % "
          f"(timeouts {sum(o.status == 'timeout' for o in valid)}, invalid "
          f"{len(out) - len(valid)})")  # fmt: skip
    source = (ROOT / module).read_text(encoding="utf-8")
    lines = source.splitlines()
    known = EQUIVALENT.get(module, {})
    all_sites = sites(source)
    n_eq = 0
    for s in surv:
        text = lines[s.line - 1].strip()
        key = site_key(s, lines, all_sites)
        why = known.get(key)
        n_eq += why is not None
        tag = f" [equivalent: {why}]" if why else ""
        print(f"  survived: line {s.line}: {s.what}: {text}{tag}")
    rest = len(valid) - n_eq
    score_ne = killed / rest if rest else float("nan")
    note = f"{killed}/{len(valid)} of a seeded sample (seed {seed}) of {n_sites} sites"
    if rerun:
        note = f"{killed}/{len(valid)} earlier survivors killed now (of {n_sites} sites)"
    if n_eq:
        print(f"{module}: {n_eq} survivor(s) listed as equivalent; without them killed "
              f"{killed}/{rest} = {100 * score_ne:.0f} %")  # fmt: skip
        note += f"; {killed}/{rest} = {100 * score_ne:.0f} % without {n_eq} equivalent"
    metric = "earlier survivors killed" if rerun else "mutants killed by its own tests"
    row("mutation", f"{module} {metric}", 100 * score, "%", note=note)
    return {"module": module, "sites": n_sites, "sampled": len(out), "killed": killed,
            "valid": len(valid), "score": score, "equivalent": n_eq,
            "score_without_equivalent": score_ne,
            "mutants": [{**asdict(o.site), "status": o.status, "seconds": o.seconds}
                        for o in out]}  # fmt: skip


def survivors(path: pathlib.Path, module: str) -> tuple[list[Site], int]:
    """The sites of ``module`` that survived in a ``--json`` file and still exist in its
    source unchanged, and how many survivors no longer match (the source moved)."""
    current = set(sites((ROOT / module).read_text(encoding="utf-8")))
    found, stale = [], 0
    for res in json.loads(path.read_text(encoding="utf-8")):
        if res.get("module") != module:  # a pooled file's last entry is the package's
            continue
        for m in res["mutants"]:
            if m["status"] != "survived":
                continue
            site = Site(**{k: m[k] for k in Site.__dataclass_fields__})
            if site in current:
                found.append(site)
            else:
                stale += 1
    return sorted(set(found), key=lambda s: (s.line, s.col, s.what)), stale


def _sites_of(path: str) -> list[Site]:
    """The mutation sites of the repository file ``path``."""
    return sites((ROOT / path).read_text(encoding="utf-8"))


def package_modules(folder: str) -> tuple[list[str], list[str]]:
    """The modules of :data:`TESTS` under ``folder`` and the ``.py`` files there without
    an entry (outside any score), each list sorted."""
    base = folder.rstrip("/") + "/"
    mapped = sorted(m for m in TESTS if m.startswith(base))
    files = sorted(str(f.relative_to(ROOT)) for f in (ROOT / folder).rglob("*.py"))
    return mapped, [f for f in files if f not in TESTS and _sites_of(f)]


def pooled_sample(modules: list[str], n: int, seed: int) -> dict[str, list[Site]]:
    """``n`` sites drawn (seeded, without replacement) from the union of ``modules``'
    sites, grouped by module: a module's expected share is its share of the sites."""
    union = [(m, s) for m in modules for s in _sites_of(m)]
    rng = np.random.default_rng(seed)
    pick = sorted(rng.choice(len(union), size=min(n, len(union)), replace=False))
    out: dict[str, list[Site]] = {}
    for i in pick:
        out.setdefault(union[i][0], []).append(union[i][1])
    return out


def pooled_summary(folder: str, results: list[dict], n_sites: int, seed: int,
                   unmapped: list[str]) -> dict:  # fmt: skip
    """The package's score over the per-module results of one pooled sample."""
    valid = sum(r["valid"] for r in results)
    killed = sum(r["killed"] for r in results)
    n_eq = sum(r["equivalent"] for r in results)
    score = killed / valid if valid else float("nan")
    rest = valid - n_eq
    score_ne = killed / rest if rest else float("nan")
    print(f"{folder} (pooled, seed {seed}): killed {killed}/{valid} = {100 * score:.0f} % of "
          f"{n_sites} sites; {killed}/{rest} = {100 * score_ne:.0f} % without {n_eq} "
          "listed equivalent")  # fmt: skip
    for r in results:
        print(f"  {r['module']}: {r['killed']}/{r['valid']} of {r['sites']} sites")
    off = {f: len(_sites_of(f)) for f in unmapped}
    if off:
        print("  outside the score (no TESTS entry): "
              + ", ".join(f"{f} ({k} sites)" for f, k in off.items()))  # fmt: skip
    note = (f"{killed}/{valid} of a pooled sample (seed {seed}) of {n_sites} sites; "
            f"{killed}/{rest} without {n_eq} equivalent; {sum(off.values())} sites in "
            f"{len(off)} unmapped files outside it")  # fmt: skip
    row("mutation", f"{folder} pooled mutants killed by their modules' tests", 100 * score,
        "%", note=note)  # fmt: skip
    return {"package": folder, "sites": n_sites, "killed": killed, "valid": valid,
            "score": score, "equivalent": n_eq, "score_without_equivalent": score_ne,
            "unmapped": off}  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("modules", nargs="*", help=f"modules of TESTS (default: all {len(TESTS)})")
    ap.add_argument("--n", type=int, default=40, help="mutants per module (default 40)")
    ap.add_argument("--seed", type=int, default=0, help="sample seed (default 0)")
    ap.add_argument(
        "--timeout",
        type=float,
        default=60.0,
        help="per-mutant timeout floor, s (default 60; at least 3x the baseline)",
    )
    ap.add_argument("--json", type=pathlib.Path, help="write every mutant's outcome here")
    ap.add_argument("--list", action="store_true", help="only list the sites and their count")
    ap.add_argument(
        "--rerun",
        type=pathlib.Path,
        action="append",
        default=[],
        metavar="JSON",
        help="run only the survivors of earlier --json files (repeatable) against the tests now",
    )
    ap.add_argument(
        "--pooled",
        type=int,
        metavar="N",
        help="with one folder: N sites drawn from all its mapped modules' sites together",
    )
    args = ap.parse_args()
    if args.pooled is not None:
        one_dir = len(args.modules) == 1 and (ROOT / args.modules[0]).is_dir()
        if not one_dir or args.rerun or args.list:
            ap.error("--pooled takes one folder (e.g. rangekit/ranging), no --rerun or --list")
        folder = args.modules[0]
        mapped, unmapped = package_modules(folder)
        if not mapped:
            ap.error(f"{folder!r} has no module with a test mapping")
        counts = {m: len(_sites_of(m)) for m in mapped}
        results = []
        for m, picked in pooled_sample(mapped, args.pooled, args.seed).items():
            out = check_module(
                m, n=0, seed=args.seed, timeout_s=args.timeout, only=picked,
                label=f"of a pooled sample (seed {args.seed})",
            )  # fmt: skip
            results.append(summary(m, out, counts[m], args.seed))
        pooled = pooled_summary(folder, results, sum(counts.values()), args.seed, unmapped)
        if args.json:
            args.json.write_text(json.dumps([*results, pooled], indent=1) + "\n", "utf-8")
        return 0
    mods = args.modules or list(TESTS)
    for m in mods:
        if m not in TESTS:
            ap.error(f"{m!r} has no test mapping; known: {', '.join(TESTS)}")
    results = []
    for m in mods:
        all_sites = sites((ROOT / m).read_text(encoding="utf-8"))
        if args.list:
            for s in all_sites:
                print(f"{m}:{s.line}:{s.col}: {s.what}")
            print(f"{m}: {len(all_sites)} sites")
            continue
        only = None
        if args.rerun:
            only, n_stale = [], 0
            for f in args.rerun:
                got, stale = survivors(f, m)
                only += [s for s in got if s not in only]
                n_stale += stale
            print(f"{m}: {len(only)} earlier survivors to re-run ({n_stale} no longer in the "
                  "source)", flush=True)  # fmt: skip
            if not only:
                continue
        out = check_module(m, n=args.n, seed=args.seed, timeout_s=args.timeout, only=only)
        results.append(summary(m, out, len(all_sites), args.seed, rerun=bool(args.rerun)))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
