"""Every command example in README.md and docs/ runs as written (issue 19 item 8).

The examples are the command lines inside fenced code blocks: lines starting with ``$ ``
(a terminal transcript: the lines after a command, up to the next ``$``, are its output,
compared exactly; ``$ echo $?`` checks the exit code) and bare ``rangekit ...`` lines (run,
exit 0 expected). Synopses (``[OPTIONS]``, ``FILE...``, ``a|b``) are not examples.

Each documentation file runs in its own empty folder, in document order, as a reader
following it would: what an earlier example writes, a later one reads. The inputs a
reader brings (their recordings, logs, a folder of sessions) are made on demand by the
builders in ``SCENE``, from rangekit's own simulators, under the names the docs use. The
commands run in process (``click.testing.CliRunner``): the same code as the console
script without its start-up. The few examples that cannot run here are listed in
``NOT_RUN`` with the reason; a listed example that disappears from the docs fails the
test, so the list stays true.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import shlex
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner
from rangekit_cli.main import cli

from rangekit.io.audio import write_audio

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

#: Examples not run, with the reason (matched on the command's text).
_EXPERIMENTS = (
    "Monte Carlo runs of minutes (the experiments run in tests/experiments/ at small trial "
    "counts; the experiment command is tested in tests/cli/test_experiment.py)"
)
NOT_RUN = {
    "rangekit experiment ahn2007": _EXPERIMENTS,
    "rangekit experiment ahn2007 --trials 2 --plots figures/": _EXPERIMENTS,
    "rangekit experiment kim2013 --trials 3 --plots figures/": _EXPERIMENTS,
    "rangekit experiment girard2011 --trials 5 --plots figures/": _EXPERIMENTS,
    "rangekit batch recordings/ -o results.csv --scheduler tcp://10.0.0.5:8786": (
        "needs a Dask scheduler at that address (the connect time-out is tested in "
        "tests/test_batch*.py with fakes)"
    ),
}


@dataclass
class Example:
    doc: str
    line: int
    command: str
    output: list[str] | None = None  # expected output lines (transcripts only)
    rc: int | None = None  # expected exit code (from `$ echo $?`, else 0 / 1+ on error)
    notes: list[str] = field(default_factory=list)


_SYNOPSIS = re.compile(r"\[|\.\.\.|(?<![\w'\"])\|(?![\w'\"]*['\"])|\b[A-Z]{2,}[A-Z0-9_.]*\b")


def _is_synopsis(command: str) -> bool:
    return bool(_SYNOPSIS.search(command.split("#", 1)[0]))


def _blocks(text: str):
    inside, start, lines = False, 0, []
    for i, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("```"):
            if inside:
                yield start, lines
                lines = []
            else:
                start = i
            inside = not inside
        elif inside:
            lines.append((i, line))


def _joined(lines):
    """Lines with shell continuations (``\\``) joined."""
    out, buf, first = [], "", 0
    for i, line in lines:
        if not buf:
            first = i
        buf = f"{buf} {line.strip()}" if buf else line
        if buf.rstrip().endswith("\\"):
            buf = buf.rstrip()[:-1]
            continue
        out.append((first, buf))
        buf = ""
    return out


def collect(path: Path) -> list[Example]:
    doc = str(path.relative_to(ROOT))
    examples: list[Example] = []
    for _, lines in _blocks(path.read_text()):
        lines = _joined(lines)
        transcript = any(ln.startswith("$ ") for _, ln in lines)
        current: Example | None = None
        for i, line in lines:
            if transcript:
                if line.startswith("$ "):
                    cmd = line[2:].strip()
                    if cmd == "echo $?":
                        current = examples[-1] if examples else None
                        if current is not None:
                            current.output = current.output or []
                            current.notes.append("rc")
                        continue
                    current = Example(doc, i, cmd, output=[])
                    examples.append(current)
                elif current is not None:
                    if "rc" in current.notes and current.rc is None and line.strip().isdigit():
                        current.rc = int(line.strip())
                    elif "rc" not in current.notes:
                        current.output.append(line.rstrip())
                continue
            cmd = line.strip()
            if "rangekit " not in cmd or _is_synopsis(cmd):
                continue
            if not cmd.startswith("rangekit ") and " && rangekit " not in cmd:
                continue
            examples.append(Example(doc, i, cmd))
    return [e for e in examples if "rangekit " in e.command or e.command.startswith("python -c ")]


# --- the inputs a reader brings ----------------------------------------------------------


def _cli(folder: Path, *args: str) -> None:
    r = CliRunner().invoke(cli, list(args), prog_name="rangekit", catch_exceptions=False)
    assert r.exit_code == 0, f"scene: rangekit {' '.join(args)} in {folder}: {r.output}"


def _mono_series(folder: Path, stem: str, names: list[str], *args: str) -> None:
    _cli(folder, "synth", "beepbeep", *args, "--mono", "-o", f"_{stem}.wav")
    for k, name in enumerate(names):
        (folder / f"_{stem}_dev{k}.wav").rename(folder / name)


def _three_phones(folder: Path) -> None:
    _mono_series(
        folder, "phones", ["phone0.wav", "phone1.wav", "phone2.wav"],
        "--position", "0,0,1", "--position", "2,0,1", "--position", "0,1.5,1", "--seed", "3",
    )  # fmt: skip


def _sweep_phones(folder: Path) -> None:
    _mono_series(
        folder, "phones", ["phone0.wav", "phone1.wav"],
        "--distance", "2", "--template", "sweep.wav", "--exchanges", "6", "--period", "1.5",
        "--ppm", "0,40", "--seed", "4",
    )  # fmt: skip


def _devs(folder: Path) -> None:
    _mono_series(
        folder, "devs", ["dev0.wav", "dev1.wav", "dev2.wav"],
        "--position", "0,0,1", "--position", "2,0,1", "--position", "0,1.5,1",
        "--exchanges", "6", "--period", "2.5", "--ppm", "0,40,-25", "--seed", "5",
    )  # fmt: skip


def _synth_to(name: str, *args: str):
    def build(folder: Path) -> None:
        _cli(folder, "synth", *args, "-o", name)

    return build


def _walk(folder: Path) -> None:
    from rangekit.sim import jiang2018

    (folder / "walk.csv").write_text(jiang2018.simulate(rng=1).log.to_csv())


def _kim(folder: Path) -> None:
    from rangekit.sim import kim2013

    r = kim2013.simulate(1, t_max_s=10, rng=1)
    r.to_log().to_csv(folder / "run.csv")
    (folder / "beacons.json").write_text(json.dumps(r.beacons.to_json()))


def _robot(folder: Path) -> None:
    from rangekit.sim.rigs import simulate_rig_run, square_rig

    simulate_rig_run(square_rig(), duration_s=60, rng=3).log.to_csv(folder / "robot.csv")


def _girard(folder: Path) -> None:
    from rangekit.sim import girard2011

    r = girard2011.simulate(rng=1)
    (folder / "steps.csv").write_text(r.steps.to_csv())
    (folder / "ranges.csv").write_text(r.ranges.to_csv())
    (folder / "plan.json").write_text(json.dumps(r.plan.to_json()))
    with open(folder / "truth.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_m", "y_m"])
        w.writerows([f"{x:.4f}", f"{y:.4f}"] for x, y in r.truth_m)


def _ahn(folder: Path) -> None:
    from rangekit.sim import ahn2007

    (folder / "imu.csv").write_text(ahn2007.imu_log_text(ahn2007.simulate_robot(600, rng=2)))
    fixes = ahn2007.position_log_text(ahn2007.simulate_pedestrian(120, rng=3))
    (folder / "fixes.csv").write_text(fixes)


def _distances(folder: Path) -> None:
    """Exact distances of transmitters 1 and 2 (``beacons.json``) to a robot at the docs'
    pose (1.2 m, 0.7 m, 34.377468 deg); the docs' ``--tx`` example is these, rounded."""
    from rangekit.sim.ultrasonic import receiver_positions

    if not (folder / "beacons.json").exists():
        _kim(folder)
    tx = {t["id"]: t for t in json.loads((folder / "beacons.json").read_text())["transmitters"]}
    rx = receiver_positions((1.2, 0.7, np.radians(34.377468)))
    rows = ["tx,d1_m,d2_m,d3_m"]
    for i in (1, 2):
        d = np.linalg.norm(rx - [tx[i]["x_m"], tx[i]["y_m"], tx[i]["z_m"]], axis=1)
        rows.append(f"{i}," + ",".join(f"{v:.9f}" for v in d))
    (folder / "d.csv").write_text("\n".join(rows) + "\n")


def _silence(folder: Path) -> None:
    write_audio(folder / "silence.wav", np.zeros((44100, 2)), fs=44100)


def _sessions(folder: Path, name: str, n: int, *args: str) -> None:
    (folder / name).mkdir(parents=True, exist_ok=True)
    for k in range(n):
        _cli(folder, "synth", "beepbeep", "--distance", str(1.0 + k), "--seed", str(k), *args,
             "-o", f"{name}/take_{k:02d}.wav")  # fmt: skip


def _archive(folder: Path) -> None:
    _sessions(folder, "archive/day1", 1)
    _sessions(folder, "archive/day2", 1)


def _echo_logs(folder: Path) -> None:
    (folder / "logs").mkdir()
    _cli(folder, "synth", "echo", "--map", "fixtures_audio/corridor_plan.json",
         "--pose", "1,0.7,90", "--pose", "1.5,0.7,90", "-o", "logs/walk.wav")  # fmt: skip


def _pairs(folder: Path) -> None:
    _mono_series(folder, "pair", ["_a.wav", "_b.wav"], "--distance", "1.5", "--seed", "6")
    for sub, name in (("phone_a", "_a.wav"), ("phone_b", "_b.wav")):
        (folder / sub).mkdir()
        (folder / name).rename(folder / sub / "take_01.wav")


def _series_csv(folder: Path) -> None:
    _cli(folder, "range", "--series", "s_dev0.wav", "s_dev1.wav", "--self-distance", "0.1",
         "--format", "csv", "-o", "series.csv")  # fmt: skip


def _results_jsonl(folder: Path) -> None:
    _sessions(folder, "_sessions", 2)
    _cli(folder, "batch", "_sessions", "--quiet", "-o", "results.jsonl")


def _ensure(folder: Path, name: str, doc: str = "") -> None:
    if not (folder / name).exists():
        SCENE.get((doc, name), SCENE[name])(folder)


def _after(names: tuple[str, ...], build):
    """``build`` once the files it reads (``names``) exist."""

    def run(folder: Path) -> None:
        for n in names:
            _ensure(folder, n)
        build(folder)

    return run


def _s_series(folder: Path) -> None:
    _cli(folder, "synth", "beepbeep", "--distance", "2", "--exchanges", "6", "--period", "1.5",
         "--ppm", "0,40", "--mono", "--seed", "1", "-o", "s.wav")  # fmt: skip


def _sweep_devs(folder: Path) -> None:
    _ensure(folder, "sweep.wav")
    _mono_series(folder, "sd", ["dev1.wav", "dev2.wav"], "--distance", "2", "--template",
                 "sweep.wav", "--seed", "9")  # fmt: skip


def _calibration_takes(folder: Path) -> None:
    _ensure(folder, "sweep.wav")
    for name, d, seed in (("a", 0.5, 21), ("b", 0.5, 22), ("c", 2, 23), ("d", 2, 24)):
        _cli(folder, "synth", "beepbeep", "--distance", str(d), "--template", "sweep.wav",
             "--seed", str(seed), "-o", f"{name}.wav")  # fmt: skip


def _tone_log(folder: Path) -> None:
    _cli(folder, "design", "sweep", "--f0", "3000", "--f1", "3400", "--duration", "0.05",
         "--fs", "64000", "-o", "tone.wav")  # fmt: skip
    _cli(folder, "synth", "beepbeep", "--distance", "2", "--template", "tone.wav",
         "--exchanges", "3", "--period", "1.5", "--fs", "64000", "--seed", "10",
         "-o", "log64k.wav")  # fmt: skip


def _oneway_takes(folder: Path) -> None:
    """A chirp played by one device and heard by another 2 m away, with a latency the
    calibration learns (three takes, ``r1.wav`` ... ``r3.wav``)."""
    from rangekit.signals import linear_sweep
    from rangekit.sim import Device
    from rangekit.sim.exchanges import render_exchanges

    probe = linear_sweep(17000.0, 20000.0, 0.1)
    write_audio(folder / "chirp.wav", probe.samples, fs=probe.fs)
    rng = np.random.default_rng(12)
    for k in (1, 2, 3):
        a = np.array([1.0, 1.0, 1.2]) + rng.uniform(-0.2, 0.2, 3)
        b = a + np.array([2.0, 0.0, 0.0])
        lifted = a + np.array([0.0, 0.0, 0.05])
        devs = [Device(speaker_m=a, mic_m=lifted), Device(speaker_m=b, mic_m=b)]
        sim = render_exchanges(devs, source=probe.samples, source_fs=probe.fs, lead_s=0.0123,
                               gap_s=0.3, rng=rng)  # fmt: skip
        write_audio(folder / f"r{k}.wav", sim.recordings[1], fs=44100.0)


def _track_csv(folder: Path) -> None:
    _girard(folder)
    _cli(folder, "track", "particle", "steps.csv", "--map", "plan.json", "--ranges",
         "ranges.csv", "--start", "1.25,1", "--particles", "2000", "-o", "track.csv")  # fmt: skip


#: name -> builder, per documentation file first (``(doc, name)``), then for every file.
SCENE = {
    ("docs/calibration.md", "exchange.wav"): _synth_to(
        "exchange.wav", "beepbeep", "--distance", "2", "--template", "sweep.wav", "--seed", "2"
    ),
    ("docs/calibration.md", "phone0.wav"): _sweep_phones,
    "exchange.wav": _synth_to("exchange.wav", "beepbeep", "--distance", "2", "--seed", "2"),
    ("docs/cli.md", "recording.wav"): _synth_to(
        "recording.wav", "beepbeep", "--distance", "2", "--template", "sweep.wav", "--seed", "7"
    ),
    "recording.wav": _synth_to("recording.wav", "beepbeep", "--distance", "3", "--seed", "7"),
    "t1.wav": _synth_to(
        "t1.wav", "beepbeep", "--distance", "1", "--template", "sweep.wav", "--seed", "11"
    ),
    "t2.wav": _synth_to(
        "t2.wav", "beepbeep", "--distance", "1", "--template", "sweep.wav", "--seed", "12"
    ),
    "t3.wav": _synth_to(
        "t3.wav", "beepbeep", "--distance", "1", "--template", "sweep.wav", "--seed", "13"
    ),
    "phone0.wav": _three_phones,
    "sweep.wav": lambda f: _cli(
        f,
        "design",
        "sweep",
        "--f0",
        "17000",
        "--f1",
        "20000",
        "--duration",
        "0.1",
        "-o",
        "sweep.wav",
    ),
    "sw.wav": _after(
        ("sweep.wav",),
        _synth_to(
            "sw.wav", "beepbeep", "--distance", "2", "--template", "sweep.wav", "--seed", "1"
        ),
    ),
    "x.wav": _synth_to("x.wav", "beepbeep", "--distance", "2", "--seed", "1"),
    "rec.wav": _synth_to("rec.wav", "beepbeep", "--distance", "2.5", "--seed", "3"),
    "ow.wav": _synth_to("ow.wav", "oneway", "--seed", "1"),
    "beacons.wav": _synth_to("beacons.wav", "oneway", "--seed", "2"),
    "srf02.wav": _synth_to(
        "srf02.wav", "echo", "--map", "fixtures_audio/corridor_plan.json", "--pose", "1,0.7,90"
    ),
    "s_dev0.wav": _s_series,
    "s.json": _s_series,
    "dev1.wav": _sweep_devs,
    "a.wav": _calibration_takes,
    "tone.wav": _tone_log,
    "log64k.wav": _tone_log,
    "chirp.wav": _oneway_takes,
    "r1.wav": _oneway_takes,
    "track.csv": _track_csv,
    "spaced.wav": _synth_to("spaced.wav", "beepbeep", "--distance", "2", "--spacing", "4000"),
    "phone_log.wav": _synth_to(
        "phone_log.wav",
        "beepbeep",
        "--distance",
        "2",
        "--exchanges",
        "4",
        "--period",
        "1.5",
        "--seed",
        "8",
    ),
    "dev0.wav": _devs,
    ("rangekit detect --help", "dev1.wav"): _sweep_devs,
    "srf02_log.wav": _synth_to(
        "srf02_log.wav",
        "echo",
        "--map",
        "fixtures_audio/corridor_plan.json",
        "--pose",
        "1,0.7,90",
        "--pose",
        "1.2,0.7,90",
        "--pose",
        "1.4,0.7,90",
    ),
    "walk.csv": _walk,
    "run.csv": _kim,
    "beacons.json": _kim,
    "robot.csv": _robot,
    "steps.csv": _girard,
    "ranges.csv": _girard,
    "plan.json": _girard,
    "truth.csv": _girard,
    "imu.csv": _ahn,
    "fixes.csv": _ahn,
    "d.csv": _distances,
    "silence.wav": _silence,
    "recordings": lambda f: _sessions(f, "recordings", 2),
    "archive": _archive,
    "logs": _echo_logs,
    "phone_a": _pairs,
    "series.csv": _after(("s_dev0.wav",), _series_csv),
    "results.jsonl": _results_jsonl,
}

#: Files that a builder makes beside the one asked for (so one call serves them all).
ALIASES = {"phone1.wav": "phone0.wav", "phone2.wav": "phone0.wav", "dev1.wav": "dev0.wav",
           "dev2.wav": "dev0.wav", "phone_b": "phone_a", "s_dev1.wav": "s_dev0.wav",
           "b.wav": "a.wav", "c.wav": "a.wav", "d.wav": "a.wav", "r*.wav": "r1.wav"}  # fmt: skip


def _inputs(args: list[str]) -> list[str]:
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a in ("-o", "--output", "--plots"):
            skip = True
            continue
        a = a.split("@")[0]  # calibrate's FILE@DISTANCE
        out.append(a.split("/")[0] if "/" in a else a)
        if "=" in a:
            out.append(a.split("=", 1)[1])
    return out


def _prepare(folder: Path, doc: str, args: list[str]) -> None:
    for token in _inputs(args):
        name = token if (doc, token) in SCENE else ALIASES.get(token, token)
        builder = SCENE.get((doc, name), SCENE.get(name))
        if builder is not None and not (folder / token).exists():
            builder(folder)


def _globbed(command: str, folder: Path) -> list[str]:
    """The words of ``command`` as a POSIX shell gives them: unquoted patterns expanded."""
    raw = shlex.split(command, comments=True, posix=False)
    words = shlex.split(command, comments=True)
    assert len(raw) == len(words), command
    out = []
    for r, w in zip(raw, words, strict=True):
        hits = sorted(p.name for p in folder.glob(w)) if "*" in r and r == w else []
        out.extend(hits or [w])
    return out


def _python(folder: Path, example: Example) -> str | None:
    """``python -c CODE [> FILE]``, run in process (``print`` into FILE when redirected)."""
    words = shlex.split(example.command)
    code, redirect = words[2], words[3:]
    assert not redirect or (len(redirect) == 2 and redirect[0] == ">"), example
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, f"<{example.doc}:{example.line}>", "exec"), {})
    except Exception as e:  # the docs' code failed: report it as the reader would see it
        return f"{example.doc}:{example.line}: {example.command}: {type(e).__name__}: {e}"
    if redirect:
        (folder / redirect[-1]).write_text(out.getvalue())
    return None


def _run(folder: Path, example: Example) -> str | None:
    """Run one example in ``folder``; a description of what went wrong, or None."""
    if example.command.startswith("python -c "):
        return _python(folder, example)
    command = example.command.split(" && ")[-1]  # `pip install . && rangekit ...`
    args = shlex.split(command, comments=True)
    assert args[0] == "rangekit", example
    _prepare(folder, example.doc, args[1:])
    args = _globbed(command, folder)
    r = CliRunner().invoke(cli, args[1:], prog_name="rangekit")
    shown = (r.stdout + r.stderr).splitlines()
    expected_rc = example.rc
    if expected_rc is None:
        expected_rc = 0 if not any("rangekit: error" in ln for ln in example.output or []) else -1
    where = f"{example.doc}:{example.line}: {command}"
    if expected_rc == -1 and r.exit_code == 0:
        return f"{where}: exit 0, the docs show an error\n{r.output}"
    if expected_rc >= 0 and r.exit_code != expected_rc:
        return f"{where}: exit {r.exit_code}, the docs say {expected_rc}\n{r.output}"
    if example.output:
        actual = [ln.rstrip() for ln in shown]
        if not _matches(example.output, actual):
            return (
                f"{where}: output differs\n--- docs\n"
                + "\n".join(example.output)
                + "\n--- now\n"
                + "\n".join(actual)
            )
    return None


def _matches(expected: list[str], actual: list[str]) -> bool:
    """``expected == actual``, where a line ``...`` stands for any run of lines (output the
    docs leave out) and ``...`` inside a line for any text (a count that depends on the
    machine), as in doctest's ELLIPSIS."""
    parts = [
        r"(?:[^\n]*\n)*?"
        if ln.strip() == "..."
        else "[^\n]*".join(map(re.escape, ln.split("..."))) + r"\n"
        for ln in expected
    ]
    return re.fullmatch("".join(parts), "".join(f"{ln}\n" for ln in actual)) is not None


def _all_examples() -> list[Example]:
    return [e for doc in DOCS for e in collect(doc)]


def _commands(command: click.Command, path: list[str]):
    yield path, command
    if isinstance(command, click.Group):
        for name in command.list_commands(click.Context(command)):
            sub = command.get_command(click.Context(command), name)
            if sub is not None and not sub.hidden:
                yield from _commands(sub, [*path, name])


def collect_help() -> dict[str, list[Example]]:
    """The example lines of every command's ``--help`` (``rangekit ...`` lines, with
    ``\\`` continuations), keyed by the command."""
    out = {}
    for path, _ in _commands(cli, []):
        r = CliRunner().invoke(cli, [*path, "--help"], prog_name="rangekit", terminal_width=200)
        assert r.exit_code == 0, (path, r.output)
        doc = " ".join(["rangekit", *path, "--help"])
        lines = [(i, ln.strip()) for i, ln in enumerate(r.output.splitlines(), 1)]
        examples = [
            Example(doc, i, cmd)
            for i, cmd in _joined(lines)
            if cmd.startswith("rangekit ") and not _is_synopsis(cmd)
        ]
        if examples:
            out[doc] = examples
    return out


HELP = collect_help()


def test_the_matcher():
    assert _matches(["a", "...", "z"], ["a", "b", "c", "z"]) and _matches(
        ["a", "...", "z"], ["a", "z"]
    )
    assert _matches(["n: ... sessions"], ["n: 3 sessions"])
    assert not _matches(["n: ... sessions"], ["n: 3 session"])
    assert not _matches(["a"], ["a", "b"]) and not _matches(["a", "b"], ["a"])
    assert _matches(["x", "..."], ["x"]) and not _matches(["x.y"], ["xzy"])  # '.' is literal


def test_the_collector_finds_the_examples():
    examples = _all_examples()
    commands = {e.command for e in examples}
    assert len(examples) >= 60  # 71 at the time of writing
    assert "rangekit range fixtures_audio/beepbeep_2p5m.wav --self-distance 0.1" in commands
    assert not any(_is_synopsis(c) for c in commands)
    commands |= {e.command for examples in HELP.values() for e in examples}
    assert set(NOT_RUN) <= commands, "a NOT_RUN entry no longer names an example"
    readme = [e for e in examples if e.doc == "README.md" and e.output]
    assert readme and readme[0].output[0].split() == ["a", "b", "distance_m", "sigma_m", "flags"]


def _run_all(examples: list[Example], folder: Path) -> list[str]:
    shutil.copytree(ROOT / "fixtures_audio", folder / "fixtures_audio")
    shutil.copytree(ROOT / "docs" / "rigs", folder / "docs" / "rigs")
    problems = []
    for example in examples:
        if example.command in NOT_RUN:
            continue
        t0 = time.perf_counter()
        try:
            problem = _run(folder, example)
        except AssertionError as e:  # a scene builder failed
            problem = f"{example.doc}:{example.line}: {example.command}: {e}"
        if os.environ.get("RANGEKIT_DOC_TIMES"):
            print(
                f"{time.perf_counter() - t0:6.2f} s  {example.doc}:{example.line} {example.command}"
            )
        if problem:
            problems.append(problem)
    return problems


@pytest.mark.parametrize("doc", [d for d in DOCS if collect(d)], ids=lambda d: d.name)
def test_examples_run_as_written(doc, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problems = _run_all(collect(doc), tmp_path)
    assert not problems, "\n\n".join(problems)


@pytest.mark.parametrize("command", sorted(HELP))
def test_help_examples_run_as_written(command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problems = _run_all(HELP[command], tmp_path)
    assert not problems, "\n\n".join(problems)
