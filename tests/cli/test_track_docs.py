"""Every ``rangekit track`` example of README.md, docs/ and ``--help`` runs as written.

The inputs are made by the simulator commands of the ``rangekit track`` Examples in
docs/cli.md (run here, in a temporary folder holding a copy of ``docs/rigs``); each example
then runs in process (the CLI's own entry point), must exit 0, and where the docs show
what it prints on stderr, print exactly that (a leading ``...`` line stands for the track
it prints on stdout).
"""

from __future__ import annotations

import contextlib
import re
import shlex
import shutil
from pathlib import Path

import pytest
from clihelp import run

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
#: A synopsis, not an example: a placeholder file name (LOG.csv, RIG.json, STEPS.csv).
_PLACEHOLDER = re.compile(r"\b[A-Z]+\.(csv|json)\b|FILTER|NAME")


def _track_section() -> str:
    text = (ROOT / "docs" / "cli.md").read_text()
    return text.split("## `rangekit track`", 1)[1].split("\n## ", 1)[0]


def _blocks(text: str) -> list[list[str]]:
    return [b.splitlines() for b in re.findall(r"```\n(.*?)```", text, flags=re.S)]


def _setup_commands() -> list[str]:
    """The ``$ python -c ...`` lines of the track Examples: they make the inputs."""
    return [ln[2:] for b in _blocks(_track_section()) for ln in b if ln.startswith("$ python -c ")]


def _shown() -> dict[str, list[str]]:
    """``$ rangekit track ...`` lines of every doc's code blocks -> the lines shown after."""
    out: dict[str, list[str]] = {}
    for f in DOCS:
        for block in _blocks(f.read_text()):
            for i, ln in enumerate(block):
                if not ln.startswith("$ rangekit track "):
                    continue
                after = []
                for nxt in block[i + 1 :]:
                    if nxt.startswith("$ "):
                        break
                    after.append(nxt)
                out[ln[2:].split(" #")[0].strip()] = after
    return out


def _inline() -> set[str]:
    """Inline ``rangekit track ...`` spans of the docs that name real files."""
    out = set()
    for f in DOCS:
        for m in re.finditer(r"`(rangekit track [^`]*)`", f.read_text()):
            cmd = " ".join(m.group(1).split())
            if re.search(r"\.(csv|json)\b", cmd) and not _PLACEHOLDER.search(cmd):
                out.add(cmd)
    return out


def _help_examples() -> set[str]:
    """The Examples of ``rangekit track --help`` and of each subcommand's help."""
    from rangekit_cli.track_cmd import SUBCOMMANDS

    out = set()
    for args in (["track", "--help"], *(["track", n, "--help"] for n in SUBCOMMANDS)):
        text = run(args).stdout.replace("\\\n", " ")
        out |= {" ".join(m.split()) for m in re.findall(r"^\s+(rangekit track .*)$", text, re.M)}
    return out


def _examples() -> dict[str, list[str]]:
    ex = {c: [] for c in _inline() | _help_examples()}
    ex.update(_shown())
    return ex


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("track_docs")
    shutil.copytree(ROOT / "docs" / "rigs", d / "docs" / "rigs")
    with contextlib.chdir(d):
        for cmd in _setup_commands():
            argv = shlex.split(cmd)
            assert argv[:2] == ["python", "-c"], cmd
            code, rest = argv[2], argv[3:]
            if rest:  # `> FILE`
                assert rest[0] == ">" and len(rest) == 2, cmd
                with open(rest[1], "w") as fh, contextlib.redirect_stdout(fh):
                    exec(code, {})
            else:
                exec(code, {})
    return d


def test_the_docs_show_examples_of_every_subcommand():
    from rangekit_cli.track_cmd import SUBCOMMANDS

    ex = _examples()
    assert len(_setup_commands()) == 6
    for name in SUBCOMMANDS:
        assert any(c.startswith(f"rangekit track {name} ") for c in ex), name


@pytest.mark.parametrize("cmd", sorted(_examples()))
def test_example_runs_as_written(folder, cmd):
    shown = _examples()[cmd]
    argv = shlex.split(cmd)
    assert argv[:2] == ["rangekit", "track"]
    with contextlib.chdir(folder):
        r = run(argv[1:])
    assert r.exit_code == 0, (cmd, r.stderr)
    if shown[:1] == ["..."]:  # the track on stdout, left out by the docs
        assert r.stdout.strip(), cmd
        shown = shown[1:]
    if shown:
        assert r.stderr.splitlines() == shown, cmd
