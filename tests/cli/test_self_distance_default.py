"""--self-distance defaults to None in every command, so the default lives once, in the
library (``TwoWaySetup().self_distance_m``), and the help shows that value (issue 19)."""

from __future__ import annotations

from pathlib import Path

import pytest
from clihelp import ok, run
from rangekit_cli.batch_cmd import batch_cmd
from rangekit_cli.range_cmd import range_cmd

from rangekit.ranging.config import TwoWaySetup

WAV = Path(__file__).resolve().parents[2] / "fixtures_audio" / "beepbeep_2p5m.wav"


@pytest.mark.parametrize("cmd", [range_cmd, batch_cmd], ids=["range", "batch"])
def test_option_default_is_none(cmd):
    (opt,) = [p for p in cmd.params if p.name == "self_distance"]
    assert opt.default is None


def test_help_shows_the_library_default():
    assert TwoWaySetup().self_distance_m == 0.0
    assert "[default: 0]" in " ".join(ok(run(["range", "--help"])).stdout.split())


def test_not_given_ranges_as_the_library_default():
    a = ok(run(["range", WAV, "--no-setup", "--format", "json"])).stdout
    b = ok(run(["range", WAV, "--no-setup", "--format", "json", "--self-distance", "0"])).stdout
    assert a == b
    r = ok(run(["range", WAV, "--no-setup", "-v"]))
    assert "self-distance 0\n" in r.stderr
