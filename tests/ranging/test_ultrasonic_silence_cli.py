"""A recording of digital silence is refused by ``rangekit range --scheme echo|oneway``.

Its windows hold no arrival (``test_ultrasonic_silence.py``), and an echo log without one
is no error (nothing in range), so a file of zeros (a muted input, a logger that never
armed) printed a table of dashes with exit 0. It is now a detection failure: one line
naming the file, exit 6, nothing written to ``-o``.
"""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner
from rangekit_cli.main import cli


@pytest.mark.parametrize(
    "args", [["--scheme", "echo", "--period", "0.07"],
             ["--scheme", "oneway", "--period", "0.2", "--tx-order", "0,1", "--channels", "1"]],
)  # fmt: skip
def test_a_file_of_zeros_is_refused(tmp_path, args):
    wav = tmp_path / "zeros.wav"
    sf.write(wav, np.zeros(192000), 192000, subtype="PCM_16")
    out = tmp_path / "r.csv"
    r = CliRunner().invoke(cli, ["range", str(wav), *args, "-o", str(out)])
    assert r.exit_code == 6, r.output
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "digital silence" in err[0] and "zeros.wav" in err[0]
    assert "Traceback" not in r.output
    assert not out.exists()


def test_one_nonzero_sample_is_not_silence(tmp_path):
    """The check is exact zeros only: one sample of 1 LSB late in the file is a recording
    (of nothing in range: exit 0, every cycle a dash)."""
    x = np.zeros(192000)
    x[150000] = 1.0 / 32768
    wav = tmp_path / "lsb.wav"
    sf.write(wav, x, 192000, subtype="PCM_16")
    r = CliRunner().invoke(cli, ["range", str(wav), "--scheme", "echo", "--period", "0.07"])
    assert r.exit_code == 0, r.output
