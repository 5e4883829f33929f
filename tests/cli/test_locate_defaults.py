"""``rangekit locate`` restates no default of the UHL solve: --method, --d-th and --r-r
are read from :func:`rangekit.localize.uhl.solve_pose` when help is shown or the command
runs (issue 19: "library defaults are copied into the CLI")."""

from __future__ import annotations

import inspect
import json

import numpy as np
from clihelp import ok, run

import rangekit.localize.uhl as uhl
from rangekit.sim.ultrasonic import receiver_positions


def test_the_help_shows_solve_poses_defaults(monkeypatch):
    real = uhl.solve_pose

    def solve_pose(tx_xyz, distances, *, r_R=0.25, method="direct", d_th=0.35):
        return real(tx_xyz, distances, r_R=r_R, method=method, d_th=d_th)

    monkeypatch.setattr(uhl, "solve_pose", solve_pose)
    text = " ".join(ok(run(["locate", "--help"])).stdout.split())
    assert "Table I. [default: direct]" in text
    assert "their line. [default: 0.35; x>=0.0]" in text
    assert "robot, m. [default: 0.19" not in text and "robot, m. [default: 0.25; x>0.0]" in text


def test_a_run_uses_and_reports_them(tmp_path):
    from rangekit.io.duhllog import Beacons

    b = Beacons([1, 2], [[0.0, 0.0, 2.0], [3.0, 0.0, 2.0]])
    p = tmp_path / "b.json"
    p.write_text(json.dumps(b.to_json()))
    rx = receiver_positions((1.2, 0.7, np.radians(30.0)))
    d = [np.linalg.norm(rx - b.position(i), axis=1) for i in (1, 2)]
    args = [f"{i}:{','.join(f'{v:.9f}' for v in di)}" for i, di in zip((1, 2), d, strict=True)]
    r = ok(run(["locate", "--beacons", p, "--tx", args[0], "--tx", args[1], "--format", "json"]))
    obj = json.loads(r.stdout)
    sig = inspect.signature(uhl.solve_pose).parameters
    assert (obj["method"], obj["d_th_m"], obj["r_R_m"]) == (
        sig["method"].default, sig["d_th"].default, sig["r_R"].default,
    )  # fmt: skip
    assert abs(obj["x_m"] - 1.2) < 1e-6 and abs(obj["heading_deg"] - 30.0) < 1e-4
