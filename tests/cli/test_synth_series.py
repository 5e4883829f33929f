"""``rangekit synth beepbeep --exchanges N``: a series for ``range --series --clock-rate``."""

from __future__ import annotations

import csv
import io
import json
import re

import numpy as np
from clihelp import assert_error, ok, run


def test_synth_series_ranges_back_with_the_clock_rate(tmp_path):
    out = tmp_path / "s.wav"
    ok(run(["synth", "beepbeep", "--distance", 2, "--exchanges", 12, "--period", 1.5,
            "--jitter", 0.1, "--ppm", "0,40", "--mono", "--seed", 1, "-o", out]))  # fmt: skip
    truth = json.loads(out.with_suffix(".json").read_text())
    assert truth["n_exchanges"] == 12 and len(truth["exchanges"]) == 12
    play = np.array([e["play_s"][0] for e in truth["exchanges"]])
    np.testing.assert_allclose(np.diff(play), 1.5, atol=1e-9)
    devs = [tmp_path / "s_dev0.wav", tmp_path / "s_dev1.wav"]
    args = ["range", "--series", *devs, "--self-distance", 0.1, "--format", "csv"]
    plain = list(csv.DictReader(io.StringIO(ok(run(args)).stdout)))
    res = ok(run([*args, "--clock-rate", "estimate"]))
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert len(rows) == len(plain) == 12
    m = re.search(r"device 1 ([+-][\d.]+) \+- ([\d.]+) ppm", res.stderr)
    assert m and abs(float(m.group(1)) - 40.0) < 1.0, res.stderr  # measured +40.0 +- 0.1
    d = np.array([float(r["distance_m"]) for r in rows])
    s = np.array([float(r["sigma_m"]) for r in rows])
    assert np.all(np.abs(d - 2.0) < 2.5 * s)  # measured |err| <= 2.9 mm, sigma ~8 mm
    # Uncorrected, the 40 ppm skew over the 0.6-0.7 s between the two plays biases every
    # range by about -c/2 * 40e-6 * 0.65 s = -4.5 mm (measured median -5.1 mm, corrected
    # -0.7 mm).
    unc = np.array([float(r["distance_m"]) for r in plain]) - 2.0
    assert np.median(unc) < np.median(d - 2.0) - 0.002


def test_series_options_need_exchanges(tmp_path):
    out = tmp_path / "x.wav"
    res = run(["synth", "beepbeep", "--distance", 2, "--period", 2, "-o", out])
    assert_error(res, 2, "--period", "--exchanges")
    assert not out.exists()
