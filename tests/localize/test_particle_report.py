"""The particle filter's input checks, mode rule and report (``rangekit track particle``)."""

from __future__ import annotations

import json
import math

import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
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


def test_checks_apply_to_what_the_mode_uses(walk):
    one = ParticleConfig(mount_angles_rad=(math.pi / 2,), mode="model")
    check_inputs(walk.plan, walk.ranges, walk.start_m, one)  # model: the readings unused
    check_inputs(walk.plan, walk.ranges, (100.0, 1.0), ParticleConfig(mode="imu"))  # no plan
    with pytest.raises(IncompatibleInputError, match="outside"):
        check_inputs(walk.plan, None, (100.0, 1.0), ParticleConfig(mode="model"))


def test_track_particles_checks_once_with_the_callers_names(walk):
    """The checks live in check_inputs; track_particles runs them, naming the inputs as
    its caller asks (the command: its files and options), and raises the same class."""
    one = ParticleConfig(mount_angles_rad=(math.pi / 2,))
    names = {"ranges_name": "r.csv", "mounts_name": "--mounts", "start_name": "--start",
             "plan_name": "plan.json"}  # fmt: skip
    with pytest.raises(IncompatibleInputError) as e:
        track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, one, names=names)
    assert str(e.value) == (
        "r.csv: has readings of sensor 1 but --mounts gives 1 sensor(s) (sensor indices 0..0)"
    )
    assert e.value.exit_code == 5
    with pytest.raises(IncompatibleInputError) as e:
        track_particles(walk.plan, walk.steps, None, (100.0, 1.0), ParticleConfig(mode="model"))
    assert str(e.value).startswith("start_xy 100,1 is outside the floor plan (x ")
    # imu mode does not use the plan: a start outside it is fine
    trk = track_particles(walk.plan, walk.steps, None, (100.0, 1.0),
                          ParticleConfig(mode="imu"), rng=0)  # fmt: skip
    assert trk.xy_m.shape == (len(walk.steps), 2)


def test_rig_that_does_not_fit_is_incompatible(tmp_path):
    from rangekit.localize.particle import rig_config
    from rangekit.rig import read_rig

    def rig(levers, kind="steps"):
        doc = {"format": "rangekit-rig", "version": 1, "units": "m",
               "anchors": [{"id": 1, "x_m": 0.0, "y_m": 0.0}],
               "body": {"tags": [{"id": i + 1, "x_m": x, "y_m": y}
                                 for i, (x, y) in enumerate(levers)]},
               "odometry": {"type": kind}}  # fmt: skip
        (tmp_path / "rig.json").write_text(json.dumps(doc))
        return read_rig(tmp_path / "rig.json")

    for r, match in ((rig([(0.0, 0.0)]), "body centre"), (rig([(0.0, 0.1)], "none"), "'none'")):
        with pytest.raises(IncompatibleInputError, match=match):
            rig_config(r, name="rig.json")
    with pytest.raises(IncompatibleInputError, match="2 mount angle"):
        rig_config(rig([(0.0, 0.1)]), mount_angles_rad=(0.0, 1.0))
    with pytest.raises(InvalidParameterError, match="n_particles"):  # a setting: exit 2
        rig_config(rig([(0.0, 0.1)]), n_particles=0)


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
