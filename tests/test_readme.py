"""The README quick start is what CI runs, and its first command's fixture exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _quick_start_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    return [b.strip() for b in re.findall(r"```\n(.*?)```", section, flags=re.S)]


def test_quick_start_has_exactly_two_commands():
    cmds = _quick_start_commands()
    assert len(cmds) == 2
    assert all("\n" not in c for c in cmds)


def test_ci_runs_the_second_command_verbatim():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert _quick_start_commands()[1] in [line.strip() for line in ci]


def test_first_command_ranges_a_shipped_fixture():
    first = _quick_start_commands()[0]
    assert first.startswith("pip install . && rangekit range fixtures_audio/")
    wav = first.split("rangekit range ", 1)[1].split()[0]
    assert (ROOT / wav).is_file()
    assert (ROOT / wav).with_suffix(".json").is_file()


# The README's sample output and every other transcript in the docs are run, in a
# temporary folder, and compared by tests/test_doc_examples.py.
