"""The code base stays `ruff check` and `ruff format --check` clean."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _ruff() -> list[str]:
    exe = shutil.which("ruff")
    if exe:
        return [exe]
    pytest.importorskip("ruff")
    return [sys.executable, "-m", "ruff"]


@pytest.mark.parametrize(
    "args", [["check", "."], ["format", "--check", "."]], ids=["check", "format"]
)
def test_ruff_clean(args):
    out = subprocess.run([*_ruff(), *args], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_library_does_not_import_click_or_cli():
    """Arrows point forward: rangekit/ never imports click or the CLI (except __main__), and
    only rangekit.plot imports matplotlib."""
    bad = []
    for p in (ROOT / "rangekit").rglob("*.py"):
        if p.name == "__main__.py":
            continue
        text = p.read_text()
        in_plot = p.relative_to(ROOT / "rangekit").parts[0] == "plot"
        mpl = "matplotlib" in text and not in_plot
        if "import click" in text or "rangekit_cli" in text or mpl:
            bad.append(str(p.relative_to(ROOT)))
    assert not bad


def test_import_rangekit_is_cheap():
    heavy = "('numba', 'scipy', 'soundfile', 'matplotlib')"
    code = f"import sys, rangekit; print(sorted(m for m in {heavy} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
