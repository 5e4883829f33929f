"""rangekit.batch.UltrasonicOptions: the one-way / echo options of a batch are typed
configuration objects (the job, the medium, probe, calibration), as the two-way ones are
(issue 19: no untyped keyword dict between the CLI and the batch ranging)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from rangekit.batch import BatchOptions, UltrasonicOptions, find_sessions, run_session
from rangekit.errors import InvalidParameterError
from rangekit.ranging.config import EchoSetup, Medium, OneWaySetup
from rangekit.sim.scenarios import synth_oneway

sys.path.insert(0, str(Path(__file__).resolve().parent / "cli"))
from clihelp import ok, run


def test_options_are_typed_and_checked():
    o = BatchOptions(scheme="oneway", oneway=OneWaySetup(period_s=0.2))
    assert isinstance(o.oneway, UltrasonicOptions) and o.oneway.setup.period_s == 0.2
    assert o.echo == UltrasonicOptions() and o.echo.kwargs() == {}  # the library's defaults
    with pytest.raises(InvalidParameterError, match="UltrasonicOptions"):
        BatchOptions(oneway={"period_s": 0.2})  # the untyped keywords are gone
    with pytest.raises(InvalidParameterError, match="EchoSetup"):
        BatchOptions(echo=UltrasonicOptions(OneWaySetup()))
    kw = UltrasonicOptions(EchoSetup(), Medium(speed_m_s=340.0)).kwargs()
    assert kw["speed_m_s"] == 340.0 and "probe" not in kw and "calibration" not in kw


def test_session_ranged_from_the_objects_equals_the_cli(tmp_path):
    syn = synth_oneway(txs_m=[(1, 0.5), (-1, 2)], pose=(0.2, 0.1, math.radians(30)), seed=1)
    syn.write(tmp_path / "ow.wav")
    (session,) = find_sessions([str(tmp_path)])
    opts = BatchOptions(
        scheme="oneway",
        oneway=UltrasonicOptions(OneWaySetup(period_s=0.2), Medium(temp_c=25.0)),
    )
    rows = run_session(session, opts)
    assert len(rows) == 6 and all(r["status"] == "ok" for r in rows)  # 2 windows x 3
    for r in rows:  # the sidecar's truth; measured within 2 mm
        assert abs(r["distance_m"] - r["true_distance_m"]) < 0.01
    out = tmp_path / "r.csv"
    ok(run(["batch", tmp_path / "ow.wav", "--scheme", "oneway", "--period", "0.2",
            "--temperature", "25", "-o", out, "-j", "1", "-q"]))  # fmt: skip
    import csv

    cli = list(csv.DictReader(out.open()))
    assert [float(r["distance_m"]) for r in cli] == pytest.approx(
        [r["distance_m"] for r in rows], abs=5e-7
    )
