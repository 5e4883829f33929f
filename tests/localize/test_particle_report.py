"""The particle filter's input checks, mode rule and report (``rangekit track particle``)."""

from __future__ import annotations

import json
import math

import pytest

from rangekit.errors import IncompatibleInputError
from rangekit.localize.particle import (
    TRACK_COLUMNS,
    ParticleConfig,
    check_inputs,
    default_mode,
    track_particles,
    track_report,
)
from rangekit.sim import girard2011


@pytest.fixture(scope="module")
def walk():
    return girard2011.simulate(rng=1)


def test_default_mode_follows_the_inputs():
    assert default_mode(plan=True, ranges=True) == "ranging"
    assert default_mode(plan=False, ranges=True) == "ranging"  # then refused: no plan
    assert default_mode(plan=True, ranges=False) == "model"
    assert default_mode(plan=False, ranges=False) == "imu"


def test_check_inputs_names_the_sensor_and_the_start(walk):
    assert walk.ranges.n_sensors == 2
    check_inputs(walk.plan, walk.ranges, walk.start_m, ParticleConfig())  # fits
    one = ParticleConfig(mount_angles_rad=(math.pi / 2,))
    with pytest.raises(IncompatibleInputError) as e:
        check_inputs(walk.plan, walk.ranges, walk.start_m, one, ranges_name="r.csv",
                     mounts_name="--mounts")  # fmt: skip
    assert str(e.value) == (
        "r.csv: has readings of sensor 1 but --mounts gives 1 sensor(s) (sensor indices 0..0)"
    )
    with pytest.raises(IncompatibleInputError, match=r"but the rig rig\.json has 1 tag"):
        check_inputs(None, walk.ranges, walk.start_m, one, rig_name="rig.json")
    check_inputs(None, None, (1e3, 1e3), one)  # no plan, no ranges: nothing to fit
    with pytest.raises(IncompatibleInputError) as e:
        check_inputs(walk.plan, None, (100.0, 1.0), ParticleConfig(), plan_name="plan.json",
                     start_name="--start")  # fmt: skip
    x0, y0, x1, y1 = walk.plan.bounds
    assert str(e.value) == (
        f"--start 100,1 is outside the floor plan plan.json (x {x0:g}..{x1:g}, y {y0:g}..{y1:g})"
    )
    # on the bounds is inside
    check_inputs(walk.plan, None, (x1, y1), ParticleConfig())


def test_report_of_a_seeded_run(walk):
    cfg = ParticleConfig(method="sir", n_particles=500)
    trk = track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, cfg, rng=1)
    rep = track_report(trk, log="steps.csv", start_xy=walk.start_m, plan="plan.json",
                       ranges="ranges.csv", seed=1)  # fmt: skip
    assert rep.summary == "particle (sir, ranging): 52 steps, nu=500, 0 re-initialisations"
    assert rep.columns == TRACK_COLUMNS and rep.rows.shape == (52, len(TRACK_COLUMNS))
    obj = json.loads(rep.format("json"))
    assert obj["mode"] == "ranging" and obj["map"] == "plan.json" and obj["rig"] is None
    assert obj["mounts_deg"] == [90.0, -90.0] and obj["seed"] == 1 and obj["events"] == []
    assert rep.parameters == {"method": "sir", "mode": "ranging", "n_particles": 500,
                              "mounts_deg": [90.0, -90.0], "lever_arms_m": None}  # fmt: skip


def test_reinitialisations_are_warnings(walk):
    # headings turned by 90 degrees: the walker walks into walls and the cloud dies
    from rangekit.io.steplog import StepLog

    s = walk.steps
    turned = StepLog(s.t_s, s.length_m, s.heading_rad + math.pi / 2, s.heading_sigma_rad)
    cfg = ParticleConfig(mode="model")
    trk = track_particles(walk.plan, turned, None, walk.start_m, cfg, rng=0)
    rep = track_report(trk, log="t.csv", start_xy=walk.start_m, plan="plan.json", seed=0)
    assert trk.events and len(rep.warnings) == len(trk.events)
    e = trk.events[0]
    assert rep.warnings[0] == f"step {e.step} (t_s={e.t_s:g}): {e.message}"
    assert rep.extra["events"][0] == {"step": e.step, "t_s": e.t_s, "kind": e.kind,
                                      "message": e.message}  # fmt: skip
    assert rep.summary.endswith(f"{len(trk.events)} re-initialisations")
