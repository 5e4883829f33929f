"""``rangekit design sweep``: the written file reads back as the designed probe."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf
from clihelp import assert_error, ok, run

from rangekit.signals.probe import linear_sweep, read_probe

#: 16-bit PCM: one quantisation step (libsndfile scales by 32767 on writing, floors).
LSB = 1.0 / 32767


def _same_probe(path, want) -> None:
    """``path`` read as a probe is ``want`` to within one 16-bit step (~3e-5)."""
    got = read_probe(path)
    assert got.fs == want.fs
    n = len(got.samples)
    # Only trailing samples below one step may quantise to 0 and be dropped as silence.
    assert n <= len(want.samples)
    assert np.max(np.abs(want.samples[n:]), initial=0.0) < LSB
    assert n > len(want.samples) - 0.001 * want.fs
    err = np.max(np.abs(got.samples - want.samples[:n]))
    assert err < 1.5 * LSB < 1e-4, err


def test_design_sweep_defaults(tmp_path):
    out = tmp_path / "sweep.wav"
    r = ok(run(["design", "sweep", "--f0", 17000, "--f1", 20000, "--duration", 0.1, "-o", out]))
    assert r.stdout == ""
    assert r.stderr.startswith(f"wrote {out}: linear sweep 17000-20000 Hz, 0.1 s (4410 samples")
    assert "16.98-20.02 kHz" in r.stderr
    info = sf.info(out)
    assert (info.channels, info.samplerate, info.subtype) == (1, 44100, "PCM_16")
    _same_probe(out, linear_sweep(17000.0, 20000.0, 0.1))


def test_design_sweep_options(tmp_path):
    out = tmp_path / "down.flac"
    args = ["--f0", 20000, "--f1", 100, "--duration", 0.25, "--fs", 48000, "--fade", 0.02]
    ok(run(["design", "sweep", *args, "--amplitude", 0.9, "-o", out]))
    assert sf.info(out).format == "FLAC"
    want = linear_sweep(20000.0, 100.0, 0.25, fs=48000.0, fade_s=0.02, amplitude=0.9)
    _same_probe(out, want)
    assert float(np.max(np.abs(read_probe(out).samples))) == pytest.approx(0.9, abs=1e-4)


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--f0", 17000, "--f1", 22050, "--duration", 0.1], ("--f1", "22050", "Nyquist")),
        (["--f0", 25000, "--f1", 1000, "--duration", 0.1, "--fs", 48000], ("--f0", "24000")),
        (["--f0", 5000, "--f1", 5000, "--duration", 0.1], ("--f0", "--f1", "5000")),
        (["--f0", 1000, "--f1", 2000, "--duration", 0], ("--duration",)),
        (["--f0", 1000, "--f1", 2000, "--duration", 700], ("--duration",)),
        (["--f0", 1000, "--f1", 2000, "--duration", 0.1, "--fade", 0.06], ("--fade",)),
        (["--f0", 1000, "--f1", 2000, "--duration", 0.1, "--amplitude", 0], ("--amplitude",)),
        (["--f0", "nan", "--f1", 2000, "--duration", 0.1], ("--f0",)),
        (["--f1", 2000, "--duration", 0.1], ("--f0",)),
    ],
)
def test_design_sweep_usage_errors(tmp_path, args, names):
    out = tmp_path / "x.wav"
    assert_error(run(["design", "sweep", *args, "-o", out]), 2, *names)
    assert not out.exists()


def test_design_sweep_unwritable_output(tmp_path):
    out = tmp_path / "no" / "x.wav"
    r = run(["design", "sweep", "--f0", 1000, "--f1", 2000, "--duration", 0.1, "-o", out])
    assert_error(r, 3, str(out))


def test_design_lists_sweep():
    assert "sweep" in ok(run(["design", "--help"])).stdout
