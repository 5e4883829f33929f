"""A generated, seeded hostile-input corpus over every reader and verb (issue 17).

Every case builds its inputs in a fresh folder, runs one ``rangekit`` command in-process
and checks the contract of ``docs/cli.md``: an exit code documented for that input
(never 70), on failure exactly one stderr line ``rangekit: error: ...`` naming the input
or option and no traceback, an empty stdout, an existing ``-o`` byte-identical and no
temporary file left, and nothing opened in the folder beside the case's (where a
hostile sidecar or link points). CPU time per case (not wall time) is bounded through
``resource``, and the peak memory of the whole run.
"""

from __future__ import annotations

import json
import os
import random
import resource
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from clihelp import run

from rangekit.ranging.calibration import Calibration

ROOT = Path(__file__).resolve().parents[2]
FIX = ROOT / "fixtures_audio"
REC = FIX / "beepbeep_2p5m.wav"
PLAN = FIX / "corridor_plan.json"
KEEP = b"an earlier result\n"
SEED = 17


@dataclass
class Case:
    name: str
    setup: Callable[[Path], None]  # builds the inputs in the case's folder
    argv: list[str]
    codes: set[int]  # documented exit codes for this input
    names: tuple[str, ...] = ()  # what the error line must name
    out: str | None = "out.txt"  # an existing -o that must survive a failure
    batch: bool = False
    extra: dict = field(default_factory=dict)


# --- hostile content builders ----------------------------------------------------------


#: A valid two-way calibration, built by the library (what ``rangekit calibrate`` writes).
VALID_CAL = Calibration(
    scheme="beepbeep", model="offset", offset_m=0.1, sigma_offset_m=0.001, latency_s=0.0,
    sigma_latency_s=0.0, speed_m_s=343.0, sigma_speed_m_s=0.0, cov_speed_offset=0.0,
    n_recordings=3, distances_m=(1.0,), rms_residual_m=0.001,
)  # fmt: skip


def _valid_cal() -> dict:
    return VALID_CAL.to_dict()


def _valid_beacons() -> dict:
    return {
        "format": "rangekit-beacons",
        "version": 1,
        "units": "m",
        "transmitters": [
            {"id": 1, "x_m": 0.0, "y_m": 0.0, "z_m": 2.5},
            {"id": 2, "x_m": 3.0, "y_m": 0.0, "z_m": 2.5},
            {"id": 3, "x_m": 0.0, "y_m": 3.0, "z_m": 2.5},
        ],
    }


def _poison(obj, path: list, value):
    """A copy of ``obj`` with the value at ``path`` replaced (raw JSON text for value)."""
    o = json.loads(json.dumps(obj))
    cur = o
    for k in path[:-1]:
        cur = cur[k]
    cur[path[-1]] = "@@V@@"
    return json.dumps(o).replace('"@@V@@"', value)


def _json_texts(valid: dict, fields: list[list]) -> list[tuple[str, bytes | str | None]]:
    """(label, content) of hostile JSON files; None content = a special file (below)."""
    v = json.dumps(valid)
    out = [
        ("empty", b""),
        ("syntax", v[:-1]),
        ("truncated", v[: len(v) // 2]),
        ("list", "[1, 2]"),
        ("deep", "[" * 5000 + "]" * 5000),
        ("deep65", "[" * 65 + "]" * 65),
        ("bigint", v[:-1] + ', "x": ' + "9" * 5000 + "}"),
        ("nul", v.replace(":", ":\x00", 1)),
        ("latin1", ('{"format": "caf\xe9"}').encode("latin-1")),
        ("utf16", v.encode("utf-16")),
        ("dir", None),
        ("fifo", None),
        ("devzero", None),
        ("missing", None),
    ]
    for f in fields:
        tag = ".".join(str(k) for k in f)
        for lab, val in [
            ("nan", "NaN"),
            ("inf", "Infinity"),
            ("-inf", "-Infinity"),
            ("1e400", "1e400"),
            ("1e308", "1e308"),
            ("true", "true"),
            ("str", '"1.0"'),
            ("null", "null"),
            ("list", "[1]"),
            ("neg", "-1e300"),
        ]:
            out.append((f"{tag}={lab}", _poison(valid, f, val)))
    return out


def _write_json_case(d: Path, name: str, content) -> None:
    p = d / name
    if content is not None:
        p.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))


def _special(kind: str):
    def make(p: Path) -> None:
        if kind == "dir":
            p.mkdir()
        elif kind == "fifo":
            os.mkfifo(p)
        elif kind == "devzero":
            os.symlink("/dev/zero", p)

    return make


def _wav_bytes(rng: random.Random) -> list[tuple[str, Callable[[Path], None]]]:
    """Hostile recordings: (label, writer)."""
    import soundfile as sf

    good = REC.read_bytes()

    def raw(data: bytes):
        return lambda p: p.write_bytes(data)

    def floats(x):
        return lambda p: sf.write(p, x, 44100, subtype="DOUBLE")

    z = np.zeros((4410, 2))
    nan = z.copy()
    nan[10, 0] = np.nan
    huge = z.copy()
    huge[10, 1] = 1e300
    out = [
        ("empty", raw(b"")),
        ("text", raw(b"not audio at all\n")),
        ("header", raw(good[:44])),
        ("half-header", raw(good[:20])),
        ("riff-only", raw(b"RIFF\xff\xff\xff\xffWAVE")),
        ("zero-frames", floats(np.zeros((0, 2)))),
        ("nan", floats(nan)),
        ("1e300", floats(huge)),
        ("mono", floats(np.zeros((4410, 1)))),
        ("silence", floats(z)),
        ("dir", _special("dir")),
        ("fifo", _special("fifo")),
        ("devzero", _special("devzero")),
        ("missing", lambda p: None),
    ]
    for i in range(24):  # seeded corruption of the real recording
        data = bytearray(good)
        kind = rng.choice(["truncate", "flip", "zero-run"])
        if kind == "truncate":
            data = data[: rng.randrange(0, 400)]
        elif kind == "flip":
            for _ in range(rng.randrange(1, 40)):
                data[rng.randrange(0, 44)] ^= 1 << rng.randrange(8)
        else:
            a = rng.randrange(0, 60)
            data[a : a + rng.randrange(1, 16)] = b"\x00" * 16
        out.append((f"{kind}{i}", raw(bytes(data))))
    return out


def _csv_texts(header: str, row: str) -> list[tuple[str, bytes | None]]:
    out = [
        ("empty", b""),
        ("header-only", (header + "\n").encode()),
        ("no-header", (row + "\n").encode()),
        ("bad-number", (header + "\n" + row.replace("1.0", "abc", 1) + "\n").encode()),
        ("nan", (header + "\n" + row.replace("1.0", "nan", 1) + "\n").encode()),
        ("inf", (header + "\n" + row.replace("1.0", "inf", 1) + "\n").encode()),
        ("wide-cell", (header + "\n" + row + "," + "x" * 200_000 + "\n").encode()),
        ("cells", (header + "\n" + row + ",1,2,3\n").encode()),
        ("latin1", (header + "\n" + row + "\n").encode() + b"\xe9\xff\n"),
        ("nul", (header + "\n" + row.replace(",", "\x00,", 1) + "\n").encode()),
        ("dup-header", (header + "," + header.split(",")[0] + "\n" + row + ",1\n").encode()),
        ("dir", None),
        ("fifo", None),
        ("devzero", None),
    ]
    return out


# --- the corpus --------------------------------------------------------------------------


def _corpus() -> list[Case]:
    rng = random.Random(SEED)
    cases: list[Case] = []

    def rec(d: Path) -> None:
        shutil.copy(REC, d / "rec.wav")

    # JSON readers: calibration, beacon files, floor plans (two verbs).
    cal_fields = [["speed_m_s"], ["offset_m"], ["sigma_offset_m"], ["n_recordings"]]
    bea_fields = [["transmitters", 0, "x_m"], ["transmitters", 1, "id"], ["version"]]
    plan = json.loads(PLAN.read_text())
    plan_fields = [["walls", 0, "from", 0], ["walls", 1, "to", 1]]
    readers = [
        ("cal", _valid_cal(), cal_fields, ["range", "rec.wav", "--calibration", "F.json"], {2, 3}),
        (
            "beacons",
            _valid_beacons(),
            bea_fields,
            ["locate", "--beacons", "F.json", "--tx", "1:2,2,2", "--tx", "2:2,2,2"],
            {3, 5},
        ),
        (
            "plan-synth",
            plan,
            plan_fields,
            ["synth", "echo", "--map", "F.json", "--pose", "1,1,90"],
            {3},
        ),
    ]
    for kind, valid, fields, argv, codes in readers:
        for label, content in _json_texts(valid, fields):

            def setup(d, content=content, label=label):
                rec(d)
                if content is None:
                    if label != "missing":
                        _special(label)(d / "F.json")
                else:
                    _write_json_case(d, "F.json", content)

            out = "out.wav" if argv[0] == "synth" else "out.txt"
            allowed = set(codes) | ({0} if label.endswith(("=1e308", "=null", "=neg")) else set())
            allowed |= {0} if label in ("deep65",) and kind == "plan-synth" else set()
            allowed |= {2} if label == "dir" else set()  # click.Path(dir_okay=False): usage
            cases.append(Case(f"json-{kind}-{label}", setup, argv, allowed, ("F.json",), out))

    # Recordings: range, detect, plot spectrogram, calibrate, --template, range --series.
    verbs = [
        (["range", "R.wav"], {3, 4, 5, 6}, "out.txt"),
        (["detect", "R.wav"], {3, 4, 6}, "out.txt"),
        (["range", "--series", "R.wav", "--format", "csv"], {3, 4, 5, 6}, "out.txt"),
        (["range", "rec.wav", "--template", "R.wav"], {3, 4, 5, 6}, "out.txt"),
        (["plot", "spectrogram", "R.wav"], {3, 4, 5}, "out.png"),
        (["calibrate", "R.wav@1", "rec.wav@1", "rec.wav@2"], {3, 4, 5, 6, 7}, "cal.json"),
    ]
    wavs = _wav_bytes(rng)
    for argv, codes, out in verbs:
        picks = wavs[:14] + rng.sample(wavs[14:], 6)
        for label, writer in picks:

            def setup(d, writer=writer):
                rec(d)
                writer(d / "R.wav")

            ok0 = {0} if label.startswith(("flip", "zero-run")) or label == "silence" else set()
            if argv[1] == "spectrogram" and (label == "mono" or label.startswith("truncate")):
                ok0 = {0}  # any readable recording can be drawn
            names = ("R.wav",)
            cases.append(
                Case(f"wav-{argv[0]}{len(argv)}-{label}", setup, argv, codes | ok0, names, out)
            )

    # CSV tables: track log, plot ranges, plot track, plot cdf.
    tables = [
        (
            ["track", "--filter", "range-ekf", "T.csv"],
            "t_s,kind,a,b,x_m,y_m,heading_rad,var_x_m2,var_y_m2,cov_xy_m2,range_m,sigma_m",
            "1.0,range,0,1,,,,,,,1.0,0.1",
            "out.txt",
        ),
        (["plot", "ranges", "T.csv"], "t_s,a,b,distance_m,sigma_m", "1.0,0,1,2.5,0.01", "out.png"),
        (["plot", "track", "T.csv"], "t_s,x_m,y_m", "1.0,1.0,2.0", "out.png"),
        (["plot", "cdf", "T.csv"], "distance_m,true_distance_m", "1.0,1.1", "out.png"),
    ]
    for argv, header, row, out in tables:
        for label, content in _csv_texts(header, row):

            def setup(d, content=content, label=label):
                if content is None:
                    _special(label)(d / "T.csv")
                else:
                    (d / "T.csv").write_bytes(content)

            lenient = label in ("nan", "inf", "header-only") and argv[1] in ("ranges", "track")
            lenient |= label in ("nan", "inf") and argv[1] == "cdf"
            lenient |= label in ("bad-number", "nul") and argv[1] == "track"  # t_s not drawn
            ok0 = {0} if lenient else set()
            cases.append(
                Case(f"csv-{argv[0]}-{argv[1]}-{label}", setup, argv, {3, 4} | ok0, ("T.csv",), out)
            )

    # Options: hostile values, each a usage error naming the option (exit 2).
    base = ["range", "rec.wav"]
    opts = [
        ([*base, "--bursts", "100000000"], "--bursts"),
        ([*base, "--bursts", "0"], "--bursts"),
        ([*base, "--spacing", "-5"], "--spacing"),
        ([*base, "--burst-len", "3"], "--burst-len"),
        ([*base, "--temperature", "nan"], "--temperature"),
        ([*base, "--temperature", "1e308"], "--temperature"),
        ([*base, "--speed-of-sound", "0"], "--speed-of-sound"),
        ([*base, "--speed-of-sound", "inf"], "--speed-of-sound"),
        ([*base, "--self-distance", "true"], "--self-distance"),
        ([*base, "--self-distance", "nan"], "--self-distance"),
        ([*base, "--self-distance", "1e400"], "--self-distance"),
        ([*base, "--clock-ppm", "-1"], "--clock-ppm"),
        ([*base, "--clock-ppm", "1e300"], "--clock-ppm"),
        ([*base, "--freq", "nan"], "--freq"),
        ([*base, "--beep-fs", "1e300"], "--beep-fs"),
        ([*base, "--format", "xml"], "--format"),
        (["range", "--scheme", "echo", "rec.wav", "--period", "0"], "--period"),
        (["range", "--scheme", "oneway", "rec.wav", "--channels", "0"], "--channels"),
        (["range", "--scheme", "oneway", "rec.wav", "--channels", "100000"], "--channels"),
        (["range", "--scheme", "oneway", "rec.wav", "--carrier", "nan"], "--carrier"),
        (["range", "--scheme", "oneway", "rec.wav", "--tx-order", "1e400"], "--tx-order"),
        (["range", "--scheme", "oneway", "rec.wav", "--q", "inf"], "--q"),
        (["detect", "rec.wav", "--bursts", "99999999999999999999"], "--bursts"),
        (["experiment", "ahn2007", "--trials", "1000000000"], "--trials"),
        (["experiment", "ahn2007", "--seed", "-1"], "--seed"),
        (["design", "beep", "--freq", "1e300"], "--freq"),
        (["design", "sweep", "--duration", "1e9"], "duration"),
        (["--memory-budget", "lots", "range", "rec.wav"], "--memory-budget"),
        (["--memory-budget", "1e999G", "range", "rec.wav"], "--memory-budget"),
        (["batch", "rec.wav", "-o", "r.csv", "--scheduler", "nonsense"], "nonsense"),
        (["batch", "rec.wav", "-o", "r.csv", "--jobs", "0"], "--jobs"),
    ]
    for i, (argv, name) in enumerate(opts):
        out = None if "-o" in argv else ("out.wav" if argv[0] == "design" else "out.txt")
        cases.append(Case(f"opt{i:02d}-{name.strip('-')}", rec, argv, {2}, (name,), out))

    # Outputs: -o that must be refused, for every verb that writes.
    writers = [
        (["range", "rec.wav"], "txt"),
        (["range", "--series", "rec.wav", "--format", "csv"], "csv"),
        (["detect", "rec.wav"], "txt"),
        (["design", "beep"], "wav"),
        (["synth", "beepbeep", "--distance", "2"], "wav"),
        (["plot", "spectrogram", "rec.wav"], "png"),
        (["calibrate", "rec.wav@1", "rec.wav@2", "rec.wav@3"], "json"),
        (["experiment", "ahn2007", "--trials", "1"], "txt"),
    ]
    for argv, suf in writers:
        for label in ("symlink", "devnull", "fifo", "dir", "nofolder", "input"):

            def setup(d, label=label, suf=suf):
                rec(d)
                (d / "precious").write_bytes(KEEP)
                t = d / f"o.{suf}"
                if label == "symlink":
                    os.symlink("precious", t)
                elif label == "fifo":
                    os.mkfifo(t)
                elif label == "dir":
                    t.mkdir()

            target = {
                "devnull": "/dev/null",
                "nofolder": f"no/such/o.{suf}",
                "input": "rec.wav",
            }.get(label, f"o.{suf}")
            codes = {3} if label == "nofolder" else {2}
            if label == "input" and argv[0] in ("design", "synth", "experiment"):
                codes = {0, 2}  # no input there: rec.wav is simply replaced by a file
                if argv[0] != "design":
                    continue
            cases.append(
                Case(f"out-{argv[0]}{len(argv)}-{label}", setup, [*argv, "-o", target], codes,
                     (target,), None, extra={"precious": True})
            )  # fmt: skip

    # Batch archives: hostile sidecars and links; error rows, nothing read outside.
    sidecars = [
        ("abs", {"files": ["/OUTSIDE/secret.wav"]}),
        ("dotdot", {"files": ["../outside/secret.wav"]}),
        ("deep-dotdot", {"files": ["sub/../../outside/secret.wav"]}),
        ("true-sd", {"files": ["rec.wav"], "self_distance_m": True}),
        ("nan-pair", '{"files": ["rec.wav"], "pairs": [{"a": NaN, "b": 1}]}'),
        ("bigint", '{"files": ["rec.wav"], "temp_c": ' + "1" * 5000 + "}"),
        ("deep", "[" * 10000 + "]" * 10000),
        ("syntax", '{"files": ["rec.wav"], '),
        ("bom-bad", b"\xef\xbb\xbf{bad"),
        ("files-str", {"files": "rec.wav"}),
        ("files-many", {"files": ["rec.wav"] * 300}),
        ("scheme", {"files": ["rec.wav"], "scheme": "sonar"}),
        ("beep-str", {"files": ["rec.wav"], "beep": {"n_bursts": "4"}}),
        ("bursts-huge", {"files": ["rec.wav"], "beep": {"n_bursts": 100000000}}),
        ("temp-1e308", {"files": ["rec.wav"], "temp_c": 1e308}),
    ]
    for label, content in sidecars:

        def setup(d, content=content):
            a = d / "arch"
            (a / "sub").mkdir(parents=True)
            shutil.copy(REC, a / "rec.wav")
            if isinstance(content, dict):
                text = json.dumps(content).replace("/OUTSIDE", str(d / "outside"))
            else:
                text = content
            (a / "rec.json").write_bytes(text if isinstance(text, bytes) else text.encode())

        cases.append(Case(f"batch-sidecar-{label}", setup, ["batch", "arch", "-q", "-j", "1"],
                          {8, 9}, ("rec.json",), None, batch=True))  # fmt: skip
    for label in ("link-out", "link-zero", "fifo", "self-loops", "fifo-json"):

        def setup(d, label=label):
            a = d / "arch"
            a.mkdir()
            (a / "x.wav").write_text("junk")  # one failing session at least
            if label == "link-out":
                os.symlink(d / "outside" / "secret.wav", a / "s.wav")
            elif label == "link-zero":
                os.symlink("/dev/zero", a / "z.json")
            elif label == "fifo":
                os.mkfifo(a / "p.wav")
            elif label == "fifo-json":
                os.mkfifo(a / "p.json")
            else:
                for i in range(3):
                    os.symlink(a, a / f"loop{i}")

        cases.append(Case(f"batch-files-{label}", setup, ["batch", "arch", "-q", "-j", "1"],
                          {8, 9}, (), None, batch=True))  # fmt: skip
    # Odd names: spaces, a leading dash, non-UTF-8 bytes, for good and bad recordings.
    odd = ["with space.wav", "-dash.wav", os.fsdecode(b"caf\xe9.wav"), "tab\there.wav"]
    for i, fname in enumerate(odd):
        shown = fname.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        for good in (True, False):

            def setup(d, fname=fname, good=good):
                if good:
                    shutil.copy(REC, d / fname)
                else:
                    (d / fname).write_text("junk")

            path = f"./{fname}"
            tag = "good" if good else "junk"
            for argv in (["range", path], ["detect", path]):
                names = () if "\ufffd" in shown else (fname,)
                cases.append(Case(f"name{i}-{tag}-{argv[0]}", setup, argv,
                                  {0} if good else {4}, names, "out.txt"))  # fmt: skip
            argv = ["batch", ".", "-q", "-j", "1"] + (["-o", "r.csv"] if good else [])
            cases.append(Case(f"name{i}-{tag}-batch", setup, argv,
                              {0} if good else {9}, (), None, batch=not good))  # fmt: skip
    return cases


CORPUS = _corpus()
_OPENED: list[str] = []
_WATCH: list[bool] = [False]


def _audit(event: str, args) -> None:
    if _WATCH[0] and event in ("open", "os.listdir", "os.scandir") and args:
        p = args[0]
        if isinstance(p, (str, bytes, os.PathLike)):
            _OPENED.append(os.fsdecode(p))


sys.addaudithook(_audit)


def test_corpus_is_large_and_seeded():
    assert len(CORPUS) >= 300
    assert len({c.name for c in CORPUS}) == len(CORPUS)
    assert [c.name for c in _corpus()] == [c.name for c in CORPUS]  # same seed, same cases


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """The case's folder (cwd), and a folder beside it whose files nothing may open."""
    import soundfile

    out = tmp_path / "outside"
    out.mkdir()
    shutil.copy(REC, out / "secret.wav")
    (out / "secret.json").write_text('{"files": ["secret.wav"]}')
    d = tmp_path / "case"
    d.mkdir()
    monkeypatch.chdir(d)
    real = soundfile.SoundFile.__init__

    def spy(self, file, *a, **k):  # libsndfile opens in C: no audit event
        if isinstance(file, (str, os.PathLike)):
            _OPENED.append(os.fspath(file))
        return real(self, file, *a, **k)

    monkeypatch.setattr(soundfile.SoundFile, "__init__", spy)
    monkeypatch.setenv("RANGEKIT_MEMORY_BUDGET", "512M")
    return d


@pytest.mark.parametrize("case", CORPUS, ids=[c.name for c in CORPUS])
def test_contract(case: Case, folder: Path):
    case.setup(folder)
    if case.out is not None:
        (folder / case.out).write_bytes(KEEP)
    argv = [*case.argv] + ([] if case.out is None else ["-o", case.out])
    if case.batch:
        argv += ["-o", "r.csv"]
    before = sorted(p.name for p in folder.iterdir())
    t0 = resource.getrusage(resource.RUSAGE_SELF)
    _OPENED.clear()
    _WATCH[0] = True
    try:
        r = run(argv)
    finally:
        _WATCH[0] = False
    t1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (t1.ru_utime - t0.ru_utime) + (t1.ru_stime - t0.ru_stime)
    assert cpu < 10.0, f"{cpu:.1f} s of CPU"
    assert r.exit_code in case.codes, (r.exit_code, r.stderr, r.exception)
    assert r.exit_code != 70 and "Traceback" not in r.stderr and "internal error" not in r.stderr
    outside = folder.parent / "outside"
    touched = [p for p in _OPENED if os.path.abspath(p).startswith(str(outside))]
    assert not touched, touched
    if case.extra.get("precious"):
        assert (folder / "precious").read_bytes() == KEEP
    if case.batch:
        assert r.stdout == ""
        rows = (folder / "r.csv").read_text(encoding="utf-8").splitlines()
        errors = [row for row in rows[1:] if ",error," in row]  # a header row, then rows
        assert errors
        for n in case.names:
            assert any(n in row for row in errors), (n, rows)
        assert str(outside) not in "\n".join(rows)  # nothing about the outside disclosed
        return
    if r.exit_code == 0:
        return
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("rangekit: error: "), r.stderr
    for n in case.names:
        assert n in lines[0], (n, lines[0])
    assert r.stdout == ""
    if case.out is not None:
        assert (folder / case.out).read_bytes() == KEEP
    assert sorted(p.name for p in folder.iterdir()) == before  # no temporary file left


def test_peak_memory_of_the_corpus_run():
    """After the corpus (this test runs last in the module): the process stayed below 1 GB."""
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    assert peak_kib < 2**20, f"{peak_kib / 2**10:.0f} MiB"
