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


def _shown_runs(text: str) -> list[tuple[str, str]]:
    """``(command, output shown)`` of every ``$ rangekit ...`` line in a code block that
    works on the shipped fixture (``$ echo $?`` shows the previous exit code)."""
    blocks, cur = [], None
    for line in text.splitlines(keepends=True):
        if line.lstrip().startswith("```"):
            if cur is None:
                cur = []
            else:
                blocks.append("".join(cur))
                cur = None
        elif cur is not None:
            cur.append(line)
    runs = []
    for block in blocks:
        if not block.startswith("$ rangekit ") or "fixtures_audio/beepbeep_2p5m.wav" not in block:
            continue
        for part in re.split(r"^\$ ", block, flags=re.M)[1:]:
            cmd, _, shown = part.partition("\n")
            runs.append((cmd, shown))
    return runs


def test_shown_output_is_what_the_commands_print():
    """The README's sample and docs/cli.md's worked example print what they show."""
    import shlex
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "cli"))
    from clihelp import run

    runs = _shown_runs((ROOT / "README.md").read_text(encoding="utf-8"))
    runs += _shown_runs((ROOT / "docs" / "cli.md").read_text(encoding="utf-8"))
    assert len(runs) >= 5, runs  # README 1; cli.md: table, csv, echo $?, detect
    import os

    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        last = None
        for cmd, shown in runs:
            if cmd == "echo $?":
                assert shown == f"{last}\n"
                continue
            r = run(shlex.split(cmd)[1:])
            assert r.stdout == shown, (cmd, r.stdout, shown)
            last = r.exit_code
    finally:
        os.chdir(cwd)
