"""Rig files (docs/rigs.md): the shipped examples parse, every problem is one line naming
the file and the field."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import InputFileError, InvalidParameterError
from rangekit.rig import parse_rig, read_rig

RIGS = Path(__file__).resolve().parents[2] / "docs" / "rigs"

GOOD = {
    "format": "rangekit-rig",
    "version": 1,
    "units": "m",
    "anchors": [{"id": 1, "x_m": 0.0, "y_m": 0.0}, {"id": 2, "x_m": 2.4, "y_m": 0.0}],
    "body": {"tags": [{"id": 1}]},
    "odometry": {"type": "differential-drive", "wheel_base_m": 0.33},
}


@pytest.mark.parametrize("name", ["kim2013", "one_tag_square", "walker_phone", "walker_steps"])
def test_shipped_rigs_parse_and_round_trip(name):
    rig = read_rig(RIGS / f"{name}.json")
    again = parse_rig(rig.to_json())
    assert np.array_equal(again.anchor_xyz_m, rig.anchor_xyz_m)
    assert np.array_equal(again.tag_lever_m, rig.tag_lever_m)
    assert again.odometry == rig.odometry
    assert again.common_bias_sigma_m == rig.common_bias_sigma_m


def test_kim_rig_is_the_papers():
    rig = read_rig(RIGS / "kim2013.json")
    assert rig.n_anchors == 6 and rig.n_tags == 3
    assert np.allclose(np.hypot(*rig.tag_lever_m[:, :2].T), 0.19)
    assert np.allclose(rig.anchor_xyz_m[:, 2], 2.011)
    assert rig.odometry.wheel_base_m == 0.33
    assert np.all(rig.anchor_bias_sigma_m == 0) and rig.common_bias_sigma_m == 0


def test_defaults():
    rig = parse_rig(GOOD)
    assert rig.anchor_sigma_m.tolist() == [0.1, 0.1]
    assert rig.anchor_bias_sigma_m.tolist() == [0.05, 0.05]
    assert rig.common_bias_sigma_m == 0.2
    assert rig.tag_lever_m.tolist() == [[0.0, 0.0, 0.0]]


def _edit(path, value):
    doc = copy.deepcopy(GOOD)
    *head, last = path
    obj = doc
    for k in head:
        obj = obj[k]
    if value is KeyError:
        del obj[last]
    else:
        obj[last] = value
    return doc


@pytest.mark.parametrize(
    ("path", "value", "needle"),
    [
        (("anchors", 1, "y_m"), KeyError, "anchors[1]: missing key 'y_m'"),
        (("anchors", 0, "x_m"), "a", "anchors[0].x_m='a' must be a number"),
        (("anchors", 1, "id"), 1, "anchors[1].id=1 repeats anchors[0].id"),
        (("anchors", 0, "sigma_m"), 0, "anchors[0].sigma_m=0 must be > 0"),
        (("anchors", 0, "colour"), "red", "anchors[0]: unknown key 'colour'"),
        (("anchors",), {}, "anchors: must be a list of anchors"),
        (("body", "tags"), [], "body.tags: needs at least one tag"),
        (("body", "tags", 0, "x_m"), float("nan"), "body.tags[0].x_m=nan must be finite"),
        (("odometry", "type"), "legs", "odometry.type='legs' must be one of"),
        (("odometry", "wheel_base_m"), KeyError, "odometry: missing key 'wheel_base_m'"),
        (("odometry", "wheel_base_m"), -1, "odometry.wheel_base_m=-1 must be > 0"),
        (("units",), "cm", "units='cm' must be 'm'"),
        (("odometry",), KeyError, "missing key 'odometry'"),
    ],
)
def test_errors_name_the_file_and_the_field(tmp_path, path, value, needle):
    with pytest.raises(InvalidParameterError) as e:
        parse_rig(_edit(path, value), name="rig.json")
    assert str(e.value).startswith("rig.json: ") and needle in str(e.value)
    p = tmp_path / "rig.json"
    p.write_text(json.dumps(_edit(path, value)))
    with pytest.raises(InputFileError) as e:
        read_rig(p)
    msg = str(e.value)
    assert "\n" not in msg
    if isinstance(value, float) and value != value:
        # NaN is not JSON: the guarded reader refuses the file before the rig is parsed.
        assert f"'{p}'" in msg and "NaN" in msg
    else:
        assert f"'{p}' is not a valid rig file: " in msg and needle in msg


def test_missing_and_non_json_files(tmp_path):
    with pytest.raises(InputFileError, match=r"nope\.json"):
        read_rig(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(InputFileError, match=r"bad\.json"):
        read_rig(tmp_path / "bad.json")
