"""Make tests/detect/probecorpus.py importable from the detector tests (importlib mode)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
