"""``rangekit design`` parses and calls rangekit.signals.design: the file it writes is the
library's byte for byte, and its errors (messages as the command printed them before the
checks moved to the library, exit codes) are unchanged."""

from __future__ import annotations

import pytest
from clihelp import ok, run

from rangekit.signals import Beep
from rangekit.signals.barker import CodedBurst
from rangekit.signals.design import design_barker, design_beep, design_sweep


def _same_bytes(cli_args, design, tmp_path, name="x.wav"):
    got, want = tmp_path / f"cli_{name}", tmp_path / f"lib_{name}"
    ok(run([*cli_args, "-o", got]))
    design.write(want)
    assert got.read_bytes() == want.read_bytes()


def test_files_are_the_librarys(tmp_path):
    _same_bytes(["design", "beep"], design_beep(), tmp_path)
    _same_bytes(["design", "beep", "--fs", 48000, "--freq", 17000, "--amplitude", 0.5],
                design_beep(Beep(f_hz=17000.0, amplitude=0.5), fs=48000.0), tmp_path)  # fmt: skip
    _same_bytes(["design", "barker"], design_barker(), tmp_path)
    ping = CodedBurst((1.0,), 40000.0, 8, 0.9, 192000.0)
    _same_bytes(["design", "barker", "--code", "+", "--cycles-per-bit", 8], design_barker(ping),
                tmp_path)  # fmt: skip
    _same_bytes(["design", "sweep", "--f0", 6000, "--f1", 2000, "--duration", 0.05, "--fs",
                 16000, "--fade", 0.01], design_sweep(6000.0, 2000.0, 0.05, fs=16000.0,
                 fade_s=0.01), tmp_path)  # fmt: skip
    _same_bytes(["design", "sweep", "--f0", 20, "--f1", 20000, "--duration", 0.2, "--fs", 48000],
                design_sweep(20.0, 20000.0, 0.2, fs=48000.0), tmp_path, "s.flac")  # fmt: skip


HINT = " (see 'rangekit design sweep --help')"
# (arguments, exit code, stderr): as the command printed them before (real runs).
ERRORS = [
    (["sweep", "--f0", 9000, "--f1", 2000, "--duration", 0.1, "--fs", 16000], 2,
     "Invalid value for --f0: 9000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000"
     + HINT),
    (["sweep", "--f0", 2000, "--f1", 8000, "--duration", 0.1, "--fs", 16000], 2,
     "Invalid value for --f1: 8000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000"
     + HINT),
    (["sweep", "--f0", 9000, "--f1", 9000, "--duration", 0.1, "--fs", 16000], 2,
     "Invalid value for --f0: 9000 Hz is not below the Nyquist frequency 8000 Hz of --fs 16000"
     + HINT),
    (["sweep", "--f0", 3000, "--f1", 3000, "--duration", 0.1], 2,
     "--f0 and --f1 are both 3000 Hz; a sweep needs two frequencies" + HINT),
    (["sweep", "--f0", 2000, "--f1", 6000, "--duration", 0.1, "--fade", 0.06], 2,
     "Invalid value for --fade: 0.06 s is longer than half of --duration 0.1 s" + HINT),
    (["beep", "--fs", 22050], 5,
     "--fs sample rate 22050 Hz is too low for the 16000 Hz beep (needs more than 36009.1 Hz)"),
    (["beep", "--amplitude", 2], 2, "amplitude=2.0 must be <= 1 (full scale)"),
    (["barker", "--fs", 50000], 2,
     "fs=50000 Hz cannot carry the 40000 Hz burst: its main lobe reaches 53333 Hz, above the "
     "Nyquist frequency 25000 Hz (needs fs > 106667 Hz)"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "code", "msg"), ERRORS, ids=[str(i) for i in range(len(ERRORS))])
def test_errors_unchanged(tmp_path, args, code, msg):
    out = tmp_path / "x.wav"
    r = run(["design", *args, "-o", out])
    assert (r.exit_code, r.stderr) == (code, f"rangekit: error: {msg}\n")
    assert not out.exists()


def test_a_half_length_fade_is_allowed(tmp_path):
    _same_bytes(["design", "sweep", "--f0", 2000, "--f1", 6000, "--duration", 0.1, "--fade",
                 0.05], design_sweep(2000.0, 6000.0, 0.1, fade_s=0.05), tmp_path)  # fmt: skip
