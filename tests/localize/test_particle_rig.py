"""The particle filter reads a rig (sensor axes and lever arms) and bounds its particle count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.floorplan import FloorPlan
from rangekit.io.steplog import RangeLog, StepLog
from rangekit.localize import particle as P
from rangekit.rig import parse_rig
from rangekit.sensors import srf02
from rangekit.sim import girard2011

#: Sensors 0.3 m left and right of the body centre (a tray held in front of the body).
LEVER = np.array([[0.0, 0.3], [0.0, -0.3]])


def _rig(tags, odometry="steps"):
    return parse_rig(
        {
            "format": "rangekit-rig",
            "version": 1,
            "units": "m",
            "anchors": [{"id": 1, "x_m": 0.0, "y_m": 0.0}],
            "body": {"tags": [{"id": i + 1, "x_m": x, "y_m": y} for i, (x, y) in enumerate(tags)]},
            "odometry": {"type": odometry}
            if odometry != "differential-drive"
            else {"type": odometry, "wheel_base_m": 0.3},
        },
        name="rig.json",
    )


def test_rig_config_takes_axes_and_lever_arms_from_the_tags():
    cfg = P.rig_config(_rig([(0.0, 0.15), (0.0, -0.15), (0.2, 0.0)]), method="sir")
    np.testing.assert_allclose(np.degrees(cfg.mount_angles_rad), [90.0, -90.0, 0.0])
    assert cfg.lever_arms_m == ((0.0, 0.15), (0.0, -0.15), (0.2, 0.0))
    assert cfg.step_sigma_m == 0.05  # the rig's odometry.length_sigma_m (default)
    given = P.rig_config(_rig([(0.0, 0.15)]), mount_angles_rad=[0.5])
    assert given.mount_angles_rad == (0.5,) and given.step_sigma_m == 0.12  # girard: unused
    assert P.rig_config(_rig([(0.0, 0.15)]), method="sir", step_sigma_m=0.2).step_sigma_m == 0.2


@pytest.mark.parametrize(
    ("tags", "odometry", "kw", "named"),
    [
        ([(0.0, 0.0)], "steps", {}, "body centre"),
        ([(0.0, 0.1)], "none", {}, "'none'"),
        ([(0.0, 0.1)], "differential-drive", {}, "'differential-drive'"),
        ([(0.0, 0.1)], "steps", {"mount_angles_rad": [0.0, 1.0]}, "2 mount angle(s)"),
    ],
)
def test_rig_config_refuses(tags, odometry, kw, named):
    # A rig that does not fit the filter: inputs each valid, not fitting together (exit 5)
    with pytest.raises(IncompatibleInputError, match=r"rig\.json") as e:
        P.rig_config(_rig(tags, odometry), name="rig.json", **kw)
    assert named in str(e.value)


def test_lever_arms_are_validated():
    with pytest.raises(InvalidParameterError, match="lever_arms_m"):
        P.ParticleConfig(lever_arms_m=((0.0, 0.1),))  # two mounts, one lever
    with pytest.raises(InvalidParameterError, match="lever_arms_m"):
        P.ParticleConfig(lever_arms_m=((0.0, math.nan), (0.0, 0.0)))


def test_the_particle_count_is_bounded():
    P.ParticleConfig(method="sir", n_particles=P.MAX_PARTICLES)
    with pytest.raises(InvalidParameterError, match="1,000,000"):
        P.ParticleConfig(method="sir", n_particles=P.MAX_PARTICLES + 1)
    # The paper's filter holds n * kappa candidate moves: 5,000,000 at most.
    P.ParticleConfig(n_particles=250_000)
    P.ParticleConfig(n_particles=500_000, kappa=10)
    with pytest.raises(InvalidParameterError, match="5,000,000"):
        P.ParticleConfig(n_particles=250_001)
    with pytest.raises(InvalidParameterError, match="5,000,000"):
        P.ParticleConfig(n_particles=1000, kappa=5001)


def test_a_lever_arm_moves_the_rays_origin():
    """Corridor y in [0, 2], walker at y = 1 heading +x: a sensor facing left reads 1 m
    from the centre, 0.7 m from a lever arm 0.3 m to the left, 1.1 m from 0.1 m right."""
    plan = FloorPlan.from_walls([((0, 0), (20, 0)), ((0, 2), (20, 2))])
    steps = StepLog([1.0], [1.0], [0.0], [0.01])
    ctx = P._StepCtx(0, 1.0, np.zeros(2), 0.0, 1.0, 0.01, np.ones(1), np.zeros(1, np.int64),
                     np.ones(1))  # fmt: skip
    xy = np.array([[5.0, 1.0], [6.0, 1.0]])
    got = []
    for lever in (None, ((0.0, 0.3),), ((0.0, -0.1),), ((0.4, 0.3),)):
        cfg = P.ParticleConfig(mount_angles_rad=(0.5 * math.pi,), lever_arms_m=lever)
        got.append(P._World(plan, cfg, use_plan=True).model(xy, xy, ctx)[:, 0])
    np.testing.assert_allclose(got, [[1.0, 1.0], [0.7, 0.7], [1.1, 1.1], [0.7, 0.7]], atol=1e-12)
    assert len(steps) == 1


def _readings_from_the_lever(walk, rng) -> RangeLog:
    """The walk's readings again, each fired from its sensor's lever arm (specular model,
    SRF02 error model: not the filter's ray model)."""
    pose = walk.reading_pose.copy()
    s = walk.ranges.sensor
    c, sn = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    pose[:, 0] += c * LEVER[s, 0] - sn * LEVER[s, 1]
    pose[:, 1] += sn * LEVER[s, 0] + c * LEVER[s, 1]
    sensor = srf02.SRF02()
    true_r = np.empty(s.size)
    for k, mount in enumerate(girard2011.MOUNT_ANGLES_RAD):
        m = s == k
        true_r[m] = srf02.model_range(walk.plan, pose[m], sensor, mount_angle_rad=mount)
    return RangeLog(walk.ranges.t_s, s, srf02.read_ranges(true_r, sensor, rng=rng))


@pytest.mark.parametrize("seed", [1, 2])
def test_the_rig_lever_arms_pay_off(seed):
    """Sensors 0.3 m off the body centre: the rig's lever arms bring the mean error from
    0.22-0.26 m (seeds 1-4, levers ignored) to 0.09-0.12 m."""
    walk = girard2011.simulate(rng=seed)
    ranges = _readings_from_the_lever(walk, np.random.default_rng(seed + 100))
    rig = _rig([tuple(v) for v in LEVER])
    err = {}
    for name, cfg in (("rig", P.rig_config(rig)), ("centre", P.ParticleConfig())):
        trk = P.track_particles(walk.plan, walk.steps, ranges, walk.start_m, cfg, rng=seed)
        err[name] = P.tracking_error(trk.xy_m, walk.truth_m).mean_m
    assert err["rig"] < 0.2, err  # measured 0.094, 0.097
    assert err["centre"] > 0.16, err  # measured 0.252, 0.224
    assert err["rig"] < 0.6 * err["centre"], err


# --- sensor axes in the rig file; rigs without anchors --------------------------------------

GIRARD_RIG = (
    __import__("pathlib").Path(__file__).parents[2] / "docs" / "rigs" / "girard2011_walker.json"
)


def test_axis_deg_sets_the_sensor_axis_and_round_trips():
    doc = _rig([(0.0, 0.15), (0.2, 0.0)]).to_json()
    doc["body"]["tags"][0]["axis_deg"] = 45.0
    rig = parse_rig(doc, name="rig.json")
    np.testing.assert_allclose(np.degrees(rig.tag_axis_rad[:1]), [45.0])
    assert np.isnan(rig.tag_axis_rad[1])
    cfg = P.rig_config(rig)  # tag 1 from axis_deg, tag 2 along its lever arm (forward)
    np.testing.assert_allclose(np.degrees(cfg.mount_angles_rad), [45.0, 0.0])
    again = parse_rig(rig.to_json(), name="rig.json")
    np.testing.assert_allclose(again.tag_axis_rad[:1], rig.tag_axis_rad[:1])
    doc["body"]["tags"][0]["axis_deg"] = 400.0
    with pytest.raises(InvalidParameterError, match=r"body.tags\[0\].axis_deg=400.0"):
        parse_rig(doc, name="rig.json")


def test_shipped_girard_rig_is_the_default_particle_setup():
    """No anchors (the filter ranges walls), sensors at the centre facing +-90 deg: the
    particle filter's default mounts, so --rig reproduces the run without it."""
    from rangekit.errors import IncompatibleInputError
    from rangekit.rig import read_rig

    rig = read_rig(GIRARD_RIG)
    assert rig.n_anchors == 0 and rig.n_tags == 2 and rig.anchor_xyz_m.shape == (0, 3)
    cfg = P.rig_config(rig)
    default = P.ParticleConfig()
    np.testing.assert_allclose(cfg.mount_angles_rad, default.mount_angles_rad, atol=1e-15)
    assert cfg.lever_arms_m == ((0.0, 0.0), (0.0, 0.0))
    with pytest.raises(IncompatibleInputError, match="ranges fixed anchors, and the rig has none"):
        rig.require_anchors("the anchor EKF")
