"""Import first in a benchmark: one core like the targets, and the repository importable.

Sets the BLAS/OpenMP thread pools to one thread (before numpy is imported) and puts the
repository root on ``sys.path`` so that ``rangekit`` imports without installation.

Bytecode: where ``PYTHONDONTWRITEBYTECODE`` is set (this machine's sessions set it), every
command a benchmark starts would compile rangekit's sources again (~0.1 s CPU, ~0.2 s wall
per command, measured on the fixture ``rangekit range``), which no installed package pays.
So the variable is dropped and the bytecode goes to :data:`PYCACHE` (outside the checkout,
``PYTHONPYCACHEPREFIX``), for this process and the commands it starts; a prefix the caller
set is kept.
"""

import os
import sys
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: Where the benchmarks' commands keep their bytecode when none was to be written.
PYCACHE = os.environ.get("PYTHONPYCACHEPREFIX") or str(
    Path(tempfile.gettempdir()) / "rangekit-bench-pycache"
)
if os.environ.pop("PYTHONDONTWRITEBYTECODE", None) is not None or sys.dont_write_bytecode:
    os.environ["PYTHONPYCACHEPREFIX"] = PYCACHE
    sys.pycache_prefix = PYCACHE
    sys.dont_write_bytecode = False
