"""CLI tests of ``rangekit track particle`` on the simulated Girard 2011 walk."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from clihelp import assert_error, ok, run

from rangekit.localize import particle as P
from rangekit.localize.particle import TRACK_COLUMNS as PARTICLE_COLUMNS
from rangekit.localize.particle import ParticleConfig, track_particles, tracking_error
from rangekit.sim import girard2011


@pytest.fixture(scope="module")
def walk():
    return girard2011.simulate(rng=3)


@pytest.fixture
def files(tmp_path, walk):
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(walk.plan.to_json()))
    steps = tmp_path / "steps.csv"
    steps.write_text(walk.steps.to_csv())
    ranges = tmp_path / "ranges.csv"
    ranges.write_text(walk.ranges.to_csv())
    return {"plan": plan, "steps": steps, "ranges": ranges, "dir": tmp_path}


def _start(walk) -> str:
    return f"{walk.start_m[0]},{walk.start_m[1]}"


def _table(text: str) -> tuple[list[str], np.ndarray]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], np.array(rows[1:], dtype=float)


def test_ranging_track_matches_library_and_truth(files, walk):
    args = ["track", "particle", "--map", files["plan"], files["steps"]]
    args += ["--ranges", files["ranges"], "--start", _start(walk), "--seed", 7]
    r = ok(run(args))
    header, t = _table(r.stdout)
    assert tuple(header) == PARTICLE_COLUMNS
    assert t.shape == (len(walk.steps), len(PARTICLE_COLUMNS))
    # The CLI is the library: same inputs and seed, same numbers.
    lib = track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, rng=7)
    np.testing.assert_allclose(t[:, 1:3], lib.xy_m, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(t[:, 3], lib.n_particles)
    # And it tracks: mean error well inside the paper's 0.13 m + margin for one seed.
    assert tracking_error(t[:, 1:3], walk.truth_m).mean_m < 0.25
    assert "particle (girard, ranging)" in r.stderr


def test_mode_follows_the_inputs_and_json(files, walk):
    base = ["track", "particle", files["steps"], "--start", _start(walk)]
    r = ok(run([*base, "--seed", 1, "--format", "json"]))
    obj = json.loads(r.stdout)
    assert obj["mode"] == "imu" and obj["method"] == "girard"
    assert obj["columns"] == list(PARTICLE_COLUMNS)
    assert len(obj["rows"]) == len(walk.steps)
    assert obj["events"] == [] and obj["seed"] == 1
    # imu mode is the dead-reckoned path moved by at most ε per step (no plan, no ranging).
    xy = np.array([row[1:3] for row in obj["rows"]])
    err = tracking_error(xy, walk.dead_reckoning_m)
    assert err.max_m < 0.25 * np.sqrt(len(walk.steps))
    r = ok(run([*base, "--map", files["plan"], "--seed", 1, "--format", "json"]))
    assert json.loads(r.stdout)["mode"] == "model"


def test_sir_method_particles_and_mounts(files, walk):
    out = files["dir"] / "sir.csv"
    args = ["track", "particle", files["steps"], "--map", files["plan"]]
    args += ["--ranges", files["ranges"], "--start", _start(walk), "--method", "sir"]
    args += ["--particles", 400, "--mounts", "90,-90", "--seed", 2, "-o", out]
    r = ok(run(args))
    assert r.stdout == ""
    _, t = _table(out.read_text())
    cfg = ParticleConfig(method="sir", n_particles=400)
    lib = track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, cfg, rng=2)
    np.testing.assert_allclose(t[:, 1:3], lib.xy_m, rtol=0, atol=1e-9)
    assert t[:, 3].max() <= 400


def test_reinitialisation_is_a_warning(files, walk):
    # A start in the wrong room against the walls: particles die and are re-spread,
    # reported as warnings, and the run still writes every step.
    plan = walk.plan
    steps = files["steps"]
    text = steps.read_text().splitlines()
    # Turn every heading by 90 degrees: the walker walks into walls.
    head = text[0].split(",").index("heading_rad")
    rows = []
    for ln in text[1:]:
        c = ln.split(",")
        c[head] = str(float(c[head]) + np.pi / 2)
        rows.append(",".join(c))
    bad = files["dir"] / "turned.csv"
    bad.write_text("\n".join([text[0], *rows]) + "\n")
    args = ["track", "particle", "--map", files["plan"], "--steps", bad]
    args += ["--start", _start(walk), "--seed", 0, "--format", "json"]
    r = ok(run(args))
    obj = json.loads(r.stdout)
    assert len(obj["rows"]) == len(walk.steps)
    assert obj["events"], "walking through walls must re-initialise"
    assert {e["kind"] for e in obj["events"]} <= {"left_map", "all_died"}
    warnings = [ln for ln in r.stderr.splitlines() if ln.startswith("warning: ")]
    assert len(warnings) == len(obj["events"])
    xy = np.array([row[1:3] for row in obj["rows"]], dtype=float)
    assert np.all(np.isfinite(xy))
    # Re-initialised clouds stay on the plan: every estimate within its bounds.
    x0, y0, x1, y1 = plan.bounds
    assert np.all((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1))


@pytest.mark.parametrize(
    ("extra", "code", "named"),
    [
        (["--start", "1,1", "--ranges", "RANGES"], 2, "--map"),
        (["--map", "PLAN"], 2, "--start"),
        (["--map", "PLAN", "--start", "1"], 2, "--start"),
        (["--map", "PLAN", "--start", "a,b"], 2, "--start"),
        (["--map", "PLAN", "--start", "1,1", "--mode", "ranging"], 2, "--ranges"),
        (
            ["--start", "1,1", "--ranges", "RANGES", "--map", "PLAN", "--mode", "model"],
            2,
            "--ranges",
        ),
        (["--map", "PLAN", "--start", "1,1", "--particles", "0"], 2, "--particles"),
        (["--map", "PLAN", "--start", "1,1", "--method", "ukf"], 2, "--method"),
        (["--map", "PLAN", "--start", "1,1", "--mounts", "x"], 2, "--mounts"),
        (["--map", "PLAN", "--start", "100,1"], 5, "--start"),
        (
            ["--map", "PLAN", "--start", "1,1", "--ranges", "RANGES", "--mounts", "90"],
            5,
            "--mounts",
        ),
    ],
)
def test_usage_and_input_errors(files, extra, code, named):
    sub = {"PLAN": files["plan"], "RANGES": files["ranges"]}
    args = ["track", "particle", files["steps"]]
    args += [sub.get(a, a) for a in extra]
    assert_error(run(args), code, named)


def test_steps_once_and_options_of_other_filters(files):
    args = ["track", "particle", files["steps"], "--steps", files["steps"]]
    assert_error(run([*args, "--start", "1,1"]), 2, "--steps")
    args = ["track", "particle", files["steps"], "--start", "1,1"]
    assert_error(run([*args, "--l-max", "1"]), 2, "--l-max")
    assert_error(run(["track", "lmax", "x.csv", "--l-max", "1", "--map", "p"]), 2, "--map")
    assert_error(run(["track", "particle", "--start", "1,1"]), 2, "STEPS.csv")
    assert_error(run(["track", "range-ekf"]), 2, "LOG")


def test_bad_files(files, walk):
    d = files["dir"]
    start = ["--start", _start(walk)]
    base = ["track", "particle", *start]
    bad_plan = d / "bad_plan.json"
    plan = walk.plan.to_json()
    plan["walls"][0]["to"] = plan["walls"][0]["from"]  # zero-length wall
    bad_plan.write_text(json.dumps(plan))
    assert_error(run([*base, files["steps"], "--map", bad_plan]), 3, "bad_plan.json")
    bad_steps = d / "bad_steps.csv"
    lines = files["steps"].read_text().splitlines()
    lines[3] = lines[3].replace(lines[3].split(",")[1], "-1.0", 1)
    bad_steps.write_text("\n".join(lines) + "\n")
    line = assert_error(run([*base, bad_steps]), 4, "bad_steps.csv", "length_m")
    assert "row 4" in line
    bad_ranges = d / "bad_ranges.csv"
    lines = files["ranges"].read_text().splitlines()
    lines[2] = "0.1,7x,1.0"
    bad_ranges.write_text("\n".join(lines) + "\n")
    args = [*base, files["steps"], "--map", files["plan"], "--ranges", bad_ranges]
    assert_error(run(args), 4, "bad_ranges.csv", "sensor")
    missing = d / "no_steps.csv"
    assert_error(run([*base, missing]), 3, "no_steps.csv")


def test_failed_run_keeps_existing_output(files, walk):
    out = files["dir"] / "track.csv"
    out.write_text("SENTINEL\n")
    args = ["track", "particle", files["dir"] / "missing.csv"]
    assert_error(run([*args, "--start", _start(walk), "-o", out]), 3, "missing.csv")
    assert out.read_text() == "SENTINEL\n"


def _rig_file(path, tags, odometry="steps"):
    doc = {
        "format": "rangekit-rig",
        "version": 1,
        "units": "m",
        "anchors": [{"id": 1, "x_m": 0.0, "y_m": 0.0}],
        "body": {"tags": [{"id": i + 1, "x_m": x, "y_m": y} for i, (x, y) in enumerate(tags)]},
        "odometry": {"type": odometry},
    }
    path.write_text(json.dumps(doc))
    return path


def test_rig_gives_the_sensor_axes_and_lever_arms(files, walk):
    rig = _rig_file(files["dir"] / "rig.json", [(0.0, 0.15), (0.0, -0.15)])
    args = ["track", "particle", files["steps"], "--map", files["plan"], "--ranges"]
    args += [files["ranges"], "--start", _start(walk), "--seed", 7, "--format", "json"]
    got = json.loads(ok(run([*args, "--rig", rig])).stdout)
    assert got["rig"] == str(rig)
    assert got["mounts_deg"] == [90.0, -90.0]
    assert got["lever_arms_m"] == [[0.0, 0.15], [0.0, -0.15]]
    # The CLI is the library: rig_config of the same rig, same seed, same numbers.
    from rangekit.rig import read_rig

    cfg = P.rig_config(read_rig(rig))
    lib = track_particles(walk.plan, walk.steps, walk.ranges, walk.start_m, cfg, rng=7)
    np.testing.assert_allclose(np.array(got["rows"])[:, 1:3], lib.xy_m, rtol=0, atol=1e-9)
    plain = json.loads(ok(run(args)).stdout)
    assert plain["rows"] != got["rows"] and plain["lever_arms_m"] is None


@pytest.mark.parametrize(
    ("tags", "odometry", "extra", "named"),
    [
        ([(0.0, 0.0), (0.0, -0.15)], "steps", [], "body centre"),
        ([(0.0, 0.15), (0.0, -0.15)], "none", [], "'none'"),
        ([(0.0, 0.15)], "steps", [], "1 tag(s)"),  # the range log has sensors 0 and 1
        ([(0.0, 0.15), (0.0, -0.15)], "steps", ["--mounts", "90"], "1 mount angle(s)"),
    ],
)
def test_rig_that_does_not_fit_is_exit_5(files, walk, tags, odometry, extra, named):
    rig = _rig_file(files["dir"] / "rig.json", tags, odometry)
    args = ["track", "particle", files["steps"], "--map", files["plan"], "--ranges"]
    args += [files["ranges"], "--start", _start(walk), "--rig", rig, *extra]
    assert_error(run(args), 5, "rig.json", named)


def test_particle_count_bound(files, walk):
    args = ["track", "particle", files["steps"], "--start", _start(walk)]
    line = assert_error(run([*args, "--particles", P.MAX_PARTICLES + 1]), 2, "--particles")
    assert f"{P.MAX_PARTICLES}" in line
    n = P.MAX_CANDIDATES // ParticleConfig().kappa + 1  # the paper's filter: n kappa moves
    assert_error(run([*args, "--particles", n]), 2, "--particles", "5,000,000", "sir")
    help_text = " ".join(ok(run(["track", "particle", "--help"])).stdout.split())
    assert f"at most {P.MAX_PARTICLES:,}" in help_text
    assert f"--method girard at most {n - 1:,}" in help_text


def test_the_old_form_with_steps_gives_the_same_track(files, walk):
    new = ["track", "particle", files["steps"], "--map", files["plan"]]
    new += ["--start", _start(walk), "--seed", 3]
    old = ["track", "--filter", "particle", "--steps", files["steps"], "--map", files["plan"]]
    old += ["--start", _start(walk), "--seed", 3]
    a, b = ok(run(new)), ok(run(old))
    assert a.stdout == b.stdout
    assert b.stderr.splitlines() == [*a.stderr.splitlines(), b.stderr.splitlines()[-1]]
    assert "deprecated" in b.stderr.splitlines()[-1]


def test_inputs_that_do_not_fit_are_exit_5_with_the_librarys_message(files, walk):
    """rangekit.localize.particle.check_inputs, run once inside track_particles, names
    the command's files and options; the command adds nothing (one line, exit 5)."""
    base = ["track", "particle", files["steps"], "--map", files["plan"]]
    line = assert_error(run([*base, "--start", "100,1"]), 5)
    x0, y0, x1, y1 = walk.plan.bounds
    assert line == (
        f"rangekit: error: --start 100,1 is outside the floor plan {files['plan']} "
        f"(x {x0:g}..{x1:g}, y {y0:g}..{y1:g})"
    )
    line = assert_error(
        run([*base, "--ranges", files["ranges"], "--start", _start(walk), "--mounts", "90"]), 5
    )
    assert line == (
        f"rangekit: error: {files['ranges']}: has readings of sensor 1 but --mounts gives 1 "
        "sensor(s) (sensor indices 0..0)"
    )
    # --mode imu does not use the plan: a start outside it runs (as in the library)
    ok(run([*base, "--mode", "imu", "--start", "100,1"]))
