"""DUHL's table and report (``rangekit track duhl`` prints them): rows, counts, summary."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError
from rangekit.io.duhllog import Beacons
from rangekit.localize import _duhl_kernels as K
from rangekit.localize.duhl import (
    OBS_STATUS,
    TRACK_COLUMNS,
    DUHLConfig,
    track_log,
    track_report,
    track_rows,
)
from rangekit.sim.kim2013 import simulate


@pytest.fixture(scope="module")
def run():
    r = simulate(1, t_max_s=10, rng=1)
    return r.to_log(), r.beacons


def test_rows_are_the_pose_and_covariance_diagonal_from_the_start(run):
    log, bcn = run
    trk = track_log(log, bcn)
    assert trk.start_index > 0  # started from a UHL solve, not at row 0
    cols, rows = track_rows(trk)
    assert cols == TRACK_COLUMNS
    k0 = trk.start_index
    assert rows.shape == (trk.t_s.size - k0, len(TRACK_COLUMNS))
    np.testing.assert_array_equal(rows[:, 0], trk.t_s[k0:])
    np.testing.assert_array_equal(rows[:, 1:4], trk.pose[k0:])
    for j, c in enumerate(("var_x_m2", "var_y_m2", "var_heading_rad2")):
        np.testing.assert_array_equal(rows[:, cols.index(c)], trk.cov[k0:, j, j])
    np.testing.assert_array_equal(rows[:, -1], trk.status[k0:])


def test_counts_group_every_status(run):
    log, bcn = run
    trk = track_log(log, bcn, config=DUHLConfig(gate_prob=0.5))
    c = trk.observation_counts()
    st = trk.obs_status
    assert c.n_rows == st.size == log.distances.t_s.size
    assert c.used + c.rejected + c.without + c.before_start == c.n_rows
    assert c.used == trk.n_observations
    assert c.rejected == np.count_nonzero(st == K.OBS_GATED) > 0  # the tight gate rejects
    assert c.before_start == np.count_nonzero(st == K.OBS_BEFORE_START) == 1
    assert set(OBS_STATUS) >= set(st.tolist())


def test_report_summary_and_json_keys(run):
    log, bcn = run
    trk = track_log(log, bcn)
    rep = track_report(trk, log="run.csv", beacons="beacons.json")
    # the numbers docs/cli.md shows for this log
    assert rep.summary == (
        "duhl: 981 poses from t_s=0.2, 51 distance rows: 49 observations used, 0 rejected, "
        "1 without an observation, 1 before the start; 1 warnings"
    )
    assert (
        rep.warnings
        == tuple(trk.warnings)
        == ("1 distance row(s) without an observation: fewer than 2 transmitters",)
    )
    obj = json.loads(rep.format("json"))
    assert obj["filter"] == "duhl" and obj["log"] == "run.csv"
    assert list(obj)[5:] == [
        "beacons", "start_t_s", "initial_pose", "config", "n_distance_rows",
        "n_observations", "n_rejected", "n_without_observation", "n_before_start", "warnings",
    ]  # fmt: skip
    assert obj["config"] == rep.parameters == {
        "wheel_base_m": 0.33, "sigma_d_m": 0.01, "k_v_m": 4e-4, "gate": None,
    }  # fmt: skip
    assert obj["initial_pose"] is None and obj["start_t_s"] == 0.2


def test_report_of_the_ranges_variant_names_it(run):
    log, bcn = run
    pose0 = [0.0, 0.0, 0.0]
    trk = track_log(log, bcn, config=DUHLConfig(variant="ranges"), initial_pose=pose0)
    rep = track_report(trk, log="run.csv", beacons="b.json", initial_pose=pose0)
    assert rep.filter_name == "duhl-ranges"
    assert rep.summary.startswith("duhl-ranges: 1001 poses from t_s=0, 51 distance rows: 51 ")
    assert json.loads(rep.format("json"))["initial_pose"] == pose0


def test_unknown_transmitter_is_named_with_its_time(run):
    log, bcn = run
    keep = [i for i in bcn.ids.tolist() if i != 2]
    fewer = Beacons(keep, [bcn.position(i) for i in keep])
    with pytest.raises(IncompatibleInputError) as e:
        track_log(log, fewer, name="run.csv", beacon_file="b.json")
    assert str(e.value) == (
        "run.csv: the distance row at t_s=0.2 names transmitter 2, which is not in the "
        f"beacon file 'b.json' (ids: {keep})"
    )
    with pytest.raises(IncompatibleInputError, match=r"^the log: .* not in the beacons "):
        track_log(log, fewer)
