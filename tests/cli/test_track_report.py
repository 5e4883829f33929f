"""``rangekit track`` prints the library's report: the same options through the library
call (``track_report`` of the tracker) and the CLI give the same stdout and stderr."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from clihelp import ok, run

from rangekit.io.duhllog import read_beacons, read_duhl_log
from rangekit.io.tracklog import read_measurement_log
from rangekit.localize import anchor_ekf, duhl, particle, range_ekf
from rangekit.rig import read_rig
from rangekit.sim import girard2011, jiang2018, rigs
from rangekit.sim.kim2013 import simulate

SQUARE = Path(__file__).resolve().parents[2] / "docs" / "rigs" / "one_tag_square.json"


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


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    p = tmp_path_factory.mktemp("walk") / "walk.csv"
    p.write_text(jiang2018.simulate(rng=1).log.to_csv())
    return p


@pytest.mark.parametrize(
    ("extra", "kw"),
    [
        ([], {}),
        (["--smooth"], {}),
        (["--gate", "0.3", "--iterations", "1"], {"gate": 0.3, "iterations": 1}),
        (["--no-gate", "--engine", "python"], {"gate": None, "engine": "python"}),
    ],
)
@pytest.mark.parametrize("fmt", ["csv", "json", "table"])
def test_range_ekf_prints_track_report(walk, extra, kw, fmt):
    r = ok(run(["track", "range-ekf", walk, "--format", fmt, "-v", *extra]))
    smooth = "--smooth" in extra
    trk = range_ekf.track_ranges(read_measurement_log(walk), smooth=smooth, name=str(walk), **kw)
    rep = range_ekf.track_report(trk, log=str(walk), smoothed=smooth, options=kw)
    assert r.stdout == rep.format(fmt)
    verbose = f"rangekit: track range-ekf: {rep.parameters_text()}"
    assert r.stderr == f"{verbose}\n" + _stderr(rep)


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    p = tmp_path_factory.mktemp("robot") / "robot.csv"
    rigs.simulate_rig_run(rigs.square_rig(), duration_s=40, rng=3).log.to_csv(p)
    return p


@pytest.mark.parametrize(
    ("extra", "kw"),
    [
        ([], {}),
        (["--smooth", "--robust", "student-t"], {"robust": "student-t"}),
        (["--initial-pose", "1,1,30", "--robust", "none"], {"robust": "none"}),
    ],
)
@pytest.mark.parametrize("fmt", ["csv", "json"])
def test_range_ekf_rig_prints_track_report(robot, extra, kw, fmt):
    r = ok(run(["track", "range-ekf", "--rig", SQUARE, robot, "--format", fmt, *extra]))
    smooth = "--smooth" in extra
    pose0 = [1.0, 1.0, math.radians(30)] if "--initial-pose" in extra else None
    trk = anchor_ekf.track_anchors(read_duhl_log(robot), read_rig(SQUARE), initial_pose=pose0,
                                   smooth=smooth, name=str(robot), **kw)  # fmt: skip
    rep = anchor_ekf.track_report(trk, log=str(robot), rig=str(SQUARE), initial_pose=pose0,
                                  smoothed=smooth, **kw)  # fmt: skip
    assert r.stdout == rep.format(fmt)
    assert r.stderr == _stderr(rep)


@pytest.fixture(scope="module")
def girard(tmp_path_factory):
    d = tmp_path_factory.mktemp("girard")
    w = girard2011.simulate(rng=1)
    (d / "plan.json").write_text(json.dumps(w.plan.to_json()))
    (d / "steps.csv").write_text(w.steps.to_csv())
    (d / "ranges.csv").write_text(w.ranges.to_csv())
    return d, w


@pytest.mark.parametrize(
    ("extra", "kw"),
    [
        (["--map", "plan.json", "--ranges", "ranges.csv"], {}),
        (["--map", "plan.json", "--method", "sir", "--particles", "300"],
         {"mode": "model", "method": "sir", "n_particles": 300}),
        (["--mounts", "10,20,30"], {"mode": "imu", "mount_angles_rad": tuple(
            math.radians(a) for a in (10, 20, 30))}),
    ],
)  # fmt: skip
@pytest.mark.parametrize("fmt", ["csv", "json", "table"])
def test_particle_prints_track_report(girard, extra, kw, fmt):
    d, w = girard
    args = [str(d / a) if a.endswith((".json", ".csv")) else a for a in extra]
    r = ok(run(["track", "particle", d / "steps.csv", "--start", "1.25,1", "--seed", 4,
                "--format", fmt, "-v", *args]))  # fmt: skip
    plan = str(d / "plan.json") if "--map" in extra else None
    ranges = str(d / "ranges.csv") if "--ranges" in extra else None
    cfg = particle.ParticleConfig(**kw)
    trk = particle.track_particles(w.plan if plan else None, w.steps, w.ranges if ranges else None,
                                   [1.25, 1.0], cfg, rng=4)  # fmt: skip
    rep = particle.track_report(trk, log=str(d / "steps.csv"), start_xy=[1.25, 1.0], plan=plan,
                                ranges=ranges, seed=4)  # fmt: skip
    assert r.stdout == rep.format(fmt)
    verbose = f"rangekit: track particle: {rep.parameters_text()}"
    assert r.stderr == f"{verbose}\n" + _stderr(rep)
