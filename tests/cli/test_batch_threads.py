"""``rangekit batch`` computes on one thread per process (docs/batch.md): the thread
variables are set when the command is loaded, before anything imports numpy or numba."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REC = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"
#: The variables docs/batch.md names (not imported from the command: loading it sets them
#: in this process too).
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

PROBE = """
import sys
from rangekit_cli.main import main
try:
    main(["batch", sys.argv[1], "-q", "-o", sys.argv[2], "--jobs", "1"])
except SystemExit:
    pass
import os, numba
print(numba.config.NUMBA_NUM_THREADS, *(os.environ.get(v) for v in sys.argv[3:]))
"""


def test_a_real_batch_computes_on_one_thread(tmp_path):
    """The check of -o loads numpy before the command's body: setting the variables there
    came too late (numba's threads stayed one per core, the variables unset)."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    out = subprocess.run(
        [sys.executable, "-c", PROBE, str(REC), str(tmp_path / "r.csv"), *THREAD_VARS],
        env=env, capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    assert out.stdout.split() == ["1"] + ["1"] * len(THREAD_VARS), out.stdout + out.stderr
    assert (tmp_path / "r.csv").read_text().count("\n") >= 2  # the session was ranged
