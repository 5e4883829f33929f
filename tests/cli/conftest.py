"""Make tests/cli/clihelp.py importable from the CLI tests (importlib import mode)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
