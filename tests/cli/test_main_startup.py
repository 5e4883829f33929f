"""``rangekit --help`` lists the commands without importing them (issue 20 item 1)."""

from __future__ import annotations

import importlib
import subprocess
import sys

import click
import pytest
from rangekit_cli.main import RangekitGroup, cli


def test_the_short_help_table_is_each_commands_own():
    assert set(RangekitGroup._short_help) == set(RangekitGroup._commands)
    for name, (mod, attr) in RangekitGroup._commands.items():
        cmd = getattr(importlib.import_module(mod), attr)
        assert not cmd.hidden
        assert RangekitGroup._short_help[name] == cmd.get_short_help_str(limit=10_000), name


@pytest.mark.parametrize("width", [40, 80, 120])
def test_the_command_list_is_what_click_writes(width):
    ctx = click.Context(cli, info_name="rangekit")
    ours = click.HelpFormatter(width=width)
    cli.format_commands(ctx, ours)
    theirs = click.HelpFormatter(width=width)
    click.Group.format_commands(cli, ctx, theirs)  # imports every command module
    assert ours.getvalue() == theirs.getvalue()
    assert "range" in ours.getvalue()


def test_help_imports_no_command_module_and_no_numpy():
    code = (
        "import sys\n"
        "from rangekit_cli.main import cli\n"
        "try:\n"
        "    cli.main(['--help'], prog_name='rangekit')\n"
        "except SystemExit:\n"
        "    pass\n"
        "bad = [m for m in sys.modules if m.startswith(('numpy', 'numba', 'scipy'))\n"
        "       or m.endswith('_cmd')]\n"
        "print('IMPORTED', sorted(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "Commands:" in out.stdout and "range " in out.stdout
    assert out.stdout.rstrip().endswith("IMPORTED []"), out.stdout[-300:]


def test_a_beep_range_imports_no_transducer_fit_nor_numba():
    """``rangekit range`` of the beep fixture (a few seconds of audio) needs neither the
    one-way transducer fit (``rangekit.detect.pathfit``, which imports ``scipy.fft``:
    ~0.18 s, once imported by ``matched`` for a decorator) nor numba (short inputs take
    the numpy paths)."""
    from pathlib import Path

    fixture = Path(__file__).resolve().parents[2] / "fixtures_audio" / "beepbeep_2p5m.wav"
    code = (
        "import sys\n"
        "from rangekit_cli.main import cli\n"
        "try:\n"
        f"    cli.main(['range', {str(fixture)!r}, '--self-distance', '0.1'],\n"
        "             prog_name='rangekit')\n"
        "except SystemExit:\n"
        "    pass\n"
        "bad = [m for m in sys.modules if m.startswith(('numba', 'scipy.fft', 'scipy.signal'))\n"
        "       or m == 'rangekit.detect.pathfit']\n"
        "print('IMPORTED', sorted(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "2.5" in out.stdout  # the range was printed (the fixture is 2.5 m)
    assert out.stdout.rstrip().endswith("IMPORTED []"), out.stdout[-400:]
