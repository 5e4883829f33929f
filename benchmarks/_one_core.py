"""Import first in a benchmark: one core like the targets, and the repository importable.

Sets the BLAS/OpenMP thread pools to one thread (before numpy is imported) and puts the
repository root on ``sys.path`` so that ``rangekit`` imports without installation.
"""

import os
import sys
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
