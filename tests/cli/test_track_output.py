"""``rangekit track`` prints :func:`rangekit.io.tracks.format_track` of the library's table
(the formatting lives in the library; the command only parses and calls)."""

from __future__ import annotations

import pytest
from clihelp import ok, run

from rangekit.io.tracks import format_track
from rangekit.localize.lmax import read_position_log, track_fixes
from rangekit.sim import ahn2007


@pytest.mark.parametrize("fmt", ["csv", "json", "table"])
def test_the_cli_prints_format_track_of_the_library_table(tmp_path, fmt):
    log = tmp_path / "fixes.csv"
    log.write_text(ahn2007.position_log_text(ahn2007.simulate_pedestrian(20, rng=3)))
    r = ok(run(["track", "lmax", log, "--l-max", "0.8", "--format", fmt]))
    t, fixes = read_position_log(log, name=str(log))
    columns, rows = track_fixes(t, fixes, l_max_m=0.8, i_star=None)
    assert r.stdout == format_track(columns, rows, fmt, filter_name="lmax", log=str(log))
