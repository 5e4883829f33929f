"""``rangekit track`` prints the library's report: the same options through the library
call (``track_report`` of the tracker) and the CLI give the same stdout and stderr."""

from __future__ import annotations

import json

import pytest
from clihelp import ok, run

from rangekit.io.duhllog import read_beacons, read_duhl_log
from rangekit.localize import duhl
from rangekit.sim.kim2013 import simulate


def _stderr(rep) -> str:
    lines = [rep.summary] if rep.summary else []
    return "".join(f"{ln}\n" for ln in [*lines, *(f"warning: {w}" for w in rep.warnings)])


@pytest.fixture(scope="module")
def kim(tmp_path_factory):
    d = tmp_path_factory.mktemp("kim")
    r = simulate(1, t_max_s=10, rng=1)
    r.to_log().to_csv(d / "run.csv")
    (d / "beacons.json").write_text(json.dumps(r.beacons.to_json()))
    return d / "run.csv", d / "beacons.json"


@pytest.mark.parametrize(
    ("sub", "extra", "kw"),
    [
        ("duhl", [], {}),
        ("duhl", ["--gate", "0.5", "--sigma-d", "0.02"], {"gate_prob": 0.5, "sigma_d_m": 0.02}),
        ("duhl-ranges", ["--initial-pose", "0,0,0"], {"variant": "ranges"}),
    ],
)
@pytest.mark.parametrize("fmt", ["csv", "json", "table"])
def test_duhl_prints_track_report(kim, sub, extra, kw, fmt):
    log, bcn = kim
    r = ok(run(["track", sub, log, "--beacons", bcn, "--format", fmt, *extra]))
    pose0 = [0.0, 0.0, 0.0] if "--initial-pose" in extra else None
    trk = duhl.track_log(read_duhl_log(log), read_beacons(bcn), config=duhl.DUHLConfig(**kw),
                         initial_pose=pose0)  # fmt: skip
    rep = duhl.track_report(trk, log=str(log), beacons=str(bcn), initial_pose=pose0)
    assert r.stdout == rep.format(fmt)
    assert r.stderr == _stderr(rep)
