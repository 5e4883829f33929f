"""rangekit.sim.scenarios: the library call of each ``rangekit synth`` command writes the
command's files byte for byte (issue 19: a thin CLI), and a series reports its progress."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.floorplan import load_floorplan
from rangekit.signals import Beep
from rangekit.sim import ShoeboxRoom
from rangekit.sim.impair import parse_impairments
from rangekit.sim.scenarios import synth_beepbeep, synth_echo, synth_oneway

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from clihelp import ok, run

PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"


def _same_files(lib_dir: Path, cli_dir: Path, names: list[str]) -> None:
    for n in names:
        assert (lib_dir / n).read_bytes() == (cli_dir / n).read_bytes(), n


def test_beepbeep_room_and_impairments_equal_the_cli(tmp_path):
    (tmp_path / "lib").mkdir()
    (tmp_path / "cli").mkdir()
    syn = synth_beepbeep(
        positions_m=[(1, 1, 1.2), (4, 2, 1.2), (2, 4, 1.2)],
        room=ShoeboxRoom((6.0, 5.0, 3.0), 0.3, 1),
        seed=2,
        impairments=parse_impairments("dc=0.02,hum_db=30"),
    )
    paths = syn.write(tmp_path / "lib" / "three.wav")
    assert [p.name for p in paths] == ["three.wav", "three.json"]
    ok(run(["synth", "beepbeep", "--position", "1,1,1.2", "--position", "4,2,1.2",
            "--position", "2,4,1.2", "--room", "6,5,3", "--seed", "2",
            "--impair", "dc=0.02,hum_db=30", "-o", tmp_path / "cli" / "three.wav"]))  # fmt: skip
    _same_files(tmp_path / "lib", tmp_path / "cli", ["three.wav", "three.json"])
    side = json.loads((tmp_path / "lib" / "three.json").read_text())
    np.testing.assert_allclose(side["setup"]["self_distance_m"], [0.1] * 3)  # library default
    assert side["files"] == ["three.wav"] and side["impairments"]["spec"]


def test_series_equals_the_cli_and_reports_progress(tmp_path):
    (tmp_path / "lib").mkdir()
    (tmp_path / "cli").mkdir()
    seen = []
    syn = synth_beepbeep(
        distance_m=2.0, exchanges=5, period_s=2.0, clock_ppm=[0, 40], jitter_s=0.01,
        mono=True, seed=1, beep=Beep(), progress=lambda d, t: seen.append((d, t)),
    )  # fmt: skip
    # 2 devices x 2 signals x 5 exchanges, each reported once, in order
    assert seen == [(i, 20) for i in range(1, 21)]
    syn.write(tmp_path / "lib" / "s.wav")
    ok(run(["synth", "beepbeep", "--distance", "2", "--exchanges", "5", "--period", "2",
            "--ppm", "0,40", "--jitter", "0.01", "--mono", "--seed", "1",
            "-o", tmp_path / "cli" / "s.wav"]))  # fmt: skip
    _same_files(tmp_path / "lib", tmp_path / "cli", ["s_dev0.wav", "s_dev1.wav", "s.json"])
    truth = json.loads((tmp_path / "lib" / "s.json").read_text())
    assert len(truth["exchanges"]) == 5 and truth["pairs"][0]["distance_m"] == 2.0


def test_oneway_and_echo_equal_the_cli(tmp_path):
    (tmp_path / "lib").mkdir()
    (tmp_path / "cli").mkdir()
    syn = synth_oneway(txs_m=[(1, 0.5), (-1, 2)], pose=(0.2, 0.1, math.radians(30)), seed=1)
    names = [p.name for p in syn.write(tmp_path / "lib" / "ow.wav")]
    assert names == ["ow.wav", "ow.json", "ow.beacons.json"]
    ok(run(["synth", "oneway", "--tx", "1,0.5", "--tx", "-1,2", "--pose", "0.2,0.1,30",
            "--seed", "1", "-o", tmp_path / "cli" / "ow.wav"]))  # fmt: skip
    _same_files(tmp_path / "lib", tmp_path / "cli", names)
    plan = load_floorplan(PLAN)
    poses = [(1.0, 1.0, math.radians(90)), (1.0, 1.5, math.radians(90))]
    syn = synth_echo(plan, poses, seed=1, map_name=str(PLAN))
    syn.write(tmp_path / "lib" / "e.wav")
    ok(run(["synth", "echo", "--map", PLAN, "--pose", "1,1,90", "--pose", "1,1.5,90",
            "--seed", "1", "-o", tmp_path / "cli" / "e.wav"]))  # fmt: skip
    _same_files(tmp_path / "lib", tmp_path / "cli", ["e.wav", "e.json"])


def test_library_checks_its_scene():
    with pytest.raises(InvalidParameterError, match="distance_m or positions_m"):
        synth_beepbeep()
    with pytest.raises(InvalidParameterError, match="at least 2"):
        synth_beepbeep(positions_m=[(0, 0, 1)])
    with pytest.raises(InvalidParameterError, match="3 values for 2 devices"):
        synth_beepbeep(distance_m=2.0, clock_ppm=[0, 1, 2])
    syn = synth_beepbeep(distance_m=1.5, snr_db=None, seed=0)
    x = syn.recordings[0]
    assert x.shape[1] == 2 and np.max(np.abs(x)) <= 1.0
