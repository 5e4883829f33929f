"""Outputs under hostile conditions (issue 17): -o never replaces an input, a link, a
device or a directory; a failed run of any verb leaves an existing -o byte-identical and
no temporary file; ``-o -`` is stdout; a full disk is a one-line error (exit 3)."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pytest
from clihelp import assert_error, ok, run

from rangekit.errors import InputFileError
from rangekit.io.guard import atomic_output

ROOT = Path(__file__).resolve().parents[2]
REC = ROOT / "fixtures_audio" / "beepbeep_2p5m.wav"
KEEP = b"precious output\n"


@pytest.fixture
def work(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copy(REC, tmp_path / "rec.wav")
    (tmp_path / "junk.wav").write_text("not audio")
    (tmp_path / "bad.csv").write_text("nothing,useful\n1,2\n")
    (tmp_path / "beacons.json").write_text("{not json")
    return tmp_path


#: (verb arguments that fail, -o name, exit code): every verb once.
FAILING = [
    (["range", "junk.wav"], "out.txt", 4),
    (["range", "--series", "junk.wav", "--format", "csv"], "out.csv", 4),
    (["range", "--scheme", "echo", "junk.wav"], "out.txt", 4),
    (["detect", "junk.wav"], "out.txt", 4),
    (["detect", "--template", "junk.wav", "rec.wav"], "out.txt", 4),
    (["design", "beep", "--freq", "30000"], "out.wav", 2),
    (["design", "sweep", "--f0", "-5"], "out.wav", 2),
    (["design", "barker", "--code", "6"], "out.wav", 2),
    (["synth", "beepbeep"], "out.wav", 2),
    (["track", "--filter", "range-ekf", "bad.csv"], "out.csv", 4),
    (["locate", "--beacons", "beacons.json", "--tx", "1:1,1,1"], "out.txt", 3),
    (["calibrate", "rec.wav", "--distance", "1"], "cal.json", 7),
    (["experiment", "ahn2007", "--trials", "0"], "out.txt", 2),
    (["plot", "spectrogram", "junk.wav"], "out.png", 4),
    (["plot", "ranges", "bad.csv"], "out.png", 4),
    (["plot", "cdf", "bad.csv"], "out.png", 4),
    (["plot", "track", "bad.csv"], "out.png", 4),
    (["plot", "matched", "junk.wav", "--scheme", "echo"], "out.png", 4),
    (["batch", "junk.wav", "--resume"], "out.csv", 2),
]


@pytest.mark.parametrize(("args", "name", "code"), FAILING, ids=lambda v: str(v))
def test_a_failed_run_leaves_an_existing_output_untouched(work, args, name, code):
    out = work / name
    out.write_bytes(KEEP)
    before = sorted(p.name for p in work.iterdir())
    r = run([*args, "-o", name])
    assert r.exit_code == code, (r.exit_code, r.stderr)
    assert "Traceback" not in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    assert r.stdout == ""
    assert out.read_bytes() == KEEP
    assert sorted(p.name for p in work.iterdir()) == before  # no .part left behind


def test_detect_exit_6_leaves_the_output_untouched(work):
    import numpy as np

    from rangekit.io.audio import write_audio

    write_audio(work / "quiet.wav", np.zeros(44100), fs=44100.0)
    (work / "out.txt").write_bytes(KEEP)
    r = run(["detect", "rec.wav", "quiet.wav", "-o", "out.txt"])
    assert r.exit_code == 6 and "quiet.wav#0" in r.stderr
    assert (work / "out.txt").read_bytes() == KEEP


@pytest.mark.parametrize(
    ("args", "target"),
    [
        (["range", "rec.wav"], "rec.wav"),
        (["range", "--series", "rec.wav", "--format", "csv"], "rec.wav"),
        (["detect", "rec.wav"], "rec.wav"),
        (["range", "rec.wav", "--template", "t.wav"], "t.wav"),
        (["range", "rec.wav", "--calibration", "cal.json"], "cal.json"),
        (["detect", "rec.wav", "--template", "t.wav"], "t.wav"),
        (["track", "--filter", "range-ekf", "bad.csv"], "bad.csv"),
        (["locate", "--beacons", "beacons.json", "--tx", "1:1,1,1"], "beacons.json"),
        (["calibrate", "rec.wav", "--distance", "1"], "rec.wav"),
        (["calibrate", "rec.wav@1", "rec2.wav@2"], "rec2.wav"),
        (["range", "rec.wav"], "hard.wav"),  # a hard link to the input
    ],
)
def test_output_that_is_an_input_is_refused(work, args, target):
    shutil.copy(REC, work / "t.wav")
    shutil.copy(REC, work / "rec2.wav")
    (work / "cal.json").write_text("{}")
    os.link(work / "rec.wav", work / "hard.wav")
    before = {p.name: p.read_bytes() for p in work.iterdir()}
    line = assert_error(run([*args, "-o", target]), 2, target, "refusing to overwrite an input")
    assert "-o" in line
    assert {p.name: p.read_bytes() for p in work.iterdir()} == before


def test_synth_never_replaces_its_map_with_the_sidecar(work):
    plan = ROOT / "fixtures_audio" / "corridor_plan.json"
    shutil.copy(plan, work / "plan.json")
    before = (work / "plan.json").read_bytes()
    r = run(["synth", "echo", "--map", "plan.json", "--pose", "1,1,90", "-o", "plan.wav"])
    assert_error(r, 2, "plan.json", "refusing to overwrite an input")
    assert (work / "plan.json").read_bytes() == before
    assert not (work / "plan.wav").exists()


@pytest.mark.parametrize("verb", [["range", "rec.wav"], ["detect", "rec.wav"]])
def test_output_through_a_symlink_device_or_directory_is_refused(work, verb):
    (work / "precious.txt").write_bytes(KEEP)
    os.symlink("precious.txt", work / "link.txt")
    assert_error(run([*verb, "-o", "link.txt"]), 2, "link.txt", "symbolic link")
    assert (work / "precious.txt").read_bytes() == KEEP
    assert (work / "link.txt").is_symlink()
    if os.path.exists("/dev/null"):
        assert_error(run([*verb, "-o", "/dev/null"]), 2, "/dev/null", "device")
    os.mkfifo(work / "fifo.txt")
    assert_error(run([*verb, "-o", "fifo.txt"]), 2, "fifo.txt", "FIFO")
    r = run([*verb, "-o", str(work)])
    assert r.exit_code == 2 and "directory" in r.stderr


def test_a_planted_part_file_is_never_followed(work):
    """The old fixed '.NAME.part' name: a link planted there must not be written through."""
    (work / "precious.txt").write_bytes(KEEP)
    for name in (".out.txt.part", ".out.csv.part"):
        os.symlink("precious.txt", work / name)
    ok(run(["range", "rec.wav", "-o", "out.txt"]))
    ok(run(["range", "--series", "rec.wav", "--format", "csv", "-o", "out.csv"]))
    assert (work / "precious.txt").read_bytes() == KEEP
    assert "distance_m" in (work / "out.txt").read_text()
    assert "distance_m" in (work / "out.csv").read_text()


def test_dash_is_stdout(work):
    r = ok(run(["range", "rec.wav", "-o", "-"]))
    assert "distance_m" in r.stdout and not (work / "-").exists()
    assert_error(run(["design", "beep", "-o", "-"]), 2, "standard output")


def test_full_disk_is_a_clean_error_and_leaves_nothing(work, monkeypatch):
    out = work / "out.txt"
    out.write_bytes(KEEP)
    with (
        pytest.raises(InputFileError, match=r"out\.txt': No space left"),
        atomic_output(out, text=True) as f,
    ):
        f.write("partial")
        raise OSError(errno.ENOSPC, "No space left on device")
    assert out.read_bytes() == KEEP
    assert sorted(p.name for p in work.iterdir()) == sorted(
        ["out.txt", "rec.wav", "junk.wav", "bad.csv", "beacons.json"]
    )

    real = os.replace

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "replace", full)
    assert_error(run(["range", "rec.wav", "-o", "out.txt"]), 3, "out.txt", "No space left")
    r = run(["range", "--series", "rec.wav", "--format", "csv", "-o", "out.txt"])
    assert_error(r, 3, "out.txt", "No space left")
    monkeypatch.setattr(os, "replace", real)
    assert out.read_bytes() == KEEP
    assert not [p for p in work.iterdir() if p.name.endswith(".part")]


@pytest.fixture
def small_disk(tmp_path):
    """A real 32 KiB tmpfs (issue 17 item 7: a full disk, not a simulated ENOSPC), or a
    skip where this process may not mount one (not root, no CAP_SYS_ADMIN)."""
    import subprocess

    mnt = tmp_path / "small"
    mnt.mkdir()
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or not shutil.which("mount"):
        pytest.skip("mounting a tmpfs needs root")
    r = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=32k,mode=0777", "tmpfs", str(mnt)],
        capture_output=True,
        text=True,
    )
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")
def test_a_really_full_disk_is_a_clean_error_and_leaves_nothing(work, small_disk):
    """The disk fills while rangekit writes (a simulated exchange is over 100 KB of 16-bit
    WAV, on a 32 KiB disk): exit 3, one line naming the output, no temporary file,
    and an existing output and everything else on that disk untouched."""
    keep = small_disk / "keep.txt"
    keep.write_bytes(KEEP)
    old = small_disk / "x.wav"
    old.write_bytes(KEEP)
    args = ["synth", "beepbeep", "--distance", "2", "--seed", "1", "-o", old]
    line = assert_error(run(args), 3, "x.wav")  # one line: no cffi tracebacks on stderr
    assert line.endswith("No space left on device")
    assert old.read_bytes() == KEEP and keep.read_bytes() == KEEP
    assert sorted(p.name for p in small_disk.iterdir()) == ["keep.txt", "x.wav"]
    r = run(["range", "--series", "rec.wav", "--format", "csv", "-o", small_disk / "r.csv"])
    ok(r)  # a small result fits: the disk is full, not broken
    assert (small_disk / "r.csv").read_text().startswith("t_s,")
