"""The one-way and echo configuration objects (``rangekit.ranging.config``): the CLI and
the library call give identical rows, every default is the library's (and the help shows
it), and a bad value is refused once, naming it (issue 19 item 1)."""

from __future__ import annotations

import inspect
from dataclasses import replace
from pathlib import Path

import pytest
from clihelp import assert_error, ok, run
from rangekit_cli.ultrasonic_options import ultrasonic_setup

from rangekit.batch import BatchOptions
from rangekit.errors import InvalidParameterError
from rangekit.io.results import format_rows
from rangekit.ranging.config import Detection, EchoSetup, Medium, OneWaySetup
from rangekit.ranging.echo import SRF02_MAX_RANGE_M, SRF02_MIN_RANGE_M, range_echo
from rangekit.ranging.oneway import range_oneway
from rangekit.ranging.run import run_range
from rangekit.signals.transducer import Transducer

PLAN = Path(__file__).resolve().parents[2] / "fixtures_audio" / "corridor_plan.json"


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    """A one-way log of 6 windows (2 ms latency) and an echo log of 3 SRF02 cycles (the
    second and third out of range: 3.5 m and 9.9 m from the far wall)."""
    d = tmp_path_factory.mktemp("ucfg")
    ow = d / "ow.wav"
    ok(run(["synth", "oneway", "--pose", "0.3,-0.2,40", "--period", 0.05, "--latency", 0.002,
            "--seed", 3, "-o", ow]))  # fmt: skip
    echo = d / "echo.wav"
    args = ["synth", "echo", "--map", PLAN, "--seed", 4, "-o", echo]
    for p in ("1,0.7,90", "3.5,1,0", "9.9,1,0"):
        args += ["--pose", p]
    ok(run(args))
    return {"ow": ow, "echo": echo}


def _same(files, scheme, setup, cli_args, medium=None, fmt="json"):
    """``rangekit range`` prints exactly the library run's rows; returns them."""
    r = ok(run(["range", "--scheme", scheme, *files, *cli_args, "--no-setup", "--format", fmt]))
    lib = run_range(files, scheme=scheme, ultrasonic=setup, medium=medium)
    rows = lib.rows()
    kw = {"meta": lib.meta, "key": "ranges"} if fmt == "json" else {}
    assert r.stdout == format_rows(rows, lib.fields, fmt, **kw)
    return rows


def test_oneway_cli_and_library_identical(recs):
    ow = [recs["ow"]]
    rows = _same(ow, "oneway", OneWaySetup(period_s=0.05, latency_s=0.002), ["--period", 0.05,
                 "--latency", 0.002])  # fmt: skip
    assert len(rows) == 6 * 3 and all(r["distance_m"] is not None for r in rows)  # 6 windows
    given = OneWaySetup(
        period_s=0.05, latency_s=0.002, tx_ids=(4, 7), min_range_m=0.5, max_range_m=8.0,
        transducer=Transducer(q=5.0), fit_transducers=False,
    )  # fmt: skip
    args = ["--period", 0.05, "--latency", 0.002, "--tx-order", "4,7", "--min-range", 0.5,
            "--max-range", 8, "--transducer-q", 5, "--temperature", 25]  # fmt: skip
    rows = _same(ow, "oneway", given, args, medium=Medium(temp_c=25.0), fmt="csv")
    assert [r["tx"] for r in rows[::3]] == [4, 7] * 3


def test_echo_cli_and_library_identical(recs):
    rows = _same([recs["echo"]], "echo", EchoSetup(period_s=0.07), ["--period", 0.07])
    assert [r["distance_m"] is None for r in rows] == [False, True, True]
    _same([recs["echo"]], "echo", EchoSetup(period_s=0.07, max_range_m=3.0, transducer=None),
          ["--period", 0.07, "--max-range", 3, "--transducer-q", 0], fmt="csv")  # fmt: skip


def test_defaults_are_the_librarys_and_the_help_shows_them():
    ow = inspect.signature(range_oneway).parameters
    for name in ("latency_s", "period_s", "min_range_m", "max_range_m", "fit_transducers"):
        assert getattr(OneWaySetup(), name) == ow[name].default, name
    assert OneWaySetup().transducer == ow["tx"].default == ow["rx"].default
    ec = inspect.signature(range_echo).parameters
    assert EchoSetup().transducer == ec["transducer"].default
    assert (EchoSetup().min_range_m, EchoSetup().max_range_m) == (
        SRF02_MIN_RANGE_M, SRF02_MAX_RANGE_M,
    )  # fmt: skip
    for k, v in Detection().kwargs().items():
        assert v == ow[k].default == ec[k].default, k
    # No option given: the objects' defaults, with only the burst's rate deferred (10 MHz).
    for scheme, kind in (("oneway", OneWaySetup), ("echo", EchoSetup)):
        cli = ultrasonic_setup({}, scheme=scheme)
        assert cli == replace(kind(), burst=kind().burst.with_fs(1e7))
    text = " ".join(ok(run(["range", "--help"])).stdout.split())
    assert "[default: oneway: 15; echo: 6 (the SRF02)]" in text
    assert "[default: oneway: 0; echo: 0.15, the SRF02 ring-down]" in text
    assert "[default: oneway: 3 receivers; echo: any]" in text
    assert "[default: oneway: 7; echo: +]" in text


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda: OneWaySetup(latency_s=-0.1), "latency_s"),
        (lambda: OneWaySetup(min_range_m=5.0, max_range_m=2.0), "max_range_m"),
        (lambda: OneWaySetup(tx_ids=()), "tx_ids"),
        (lambda: OneWaySetup(tx_ids=(1, 2.5)), "tx_ids"),
        (lambda: OneWaySetup(channels=0), "channels"),
        (lambda: OneWaySetup(burst="barker"), "burst"),
        (lambda: EchoSetup(period_s=0.0), "period_s"),
        (lambda: EchoSetup(transducer=4.0), "transducer"),
        (lambda: EchoSetup(detection={"k_noise": 3}), "detection"),
        (lambda: Detection(k_noise=0.0), "k_noise"),
        (lambda: Detection(rel_threshold=1.5), "rel_threshold"),
        (lambda: Detection(block=8), "block"),
        (lambda: run_range(["x.wav"], scheme="echo", ultrasonic=OneWaySetup()), "OneWaySetup"),
        (lambda: BatchOptions(scheme="echo", echo=OneWaySetup()), "EchoSetup"),
    ],
)
def test_bad_values_are_refused_naming_them(make, name):
    with pytest.raises(InvalidParameterError, match=name):
        make()


def test_batch_options_take_the_objects():
    setup = OneWaySetup(period_s=0.2, tx_ids=(1, 2))
    opts = BatchOptions(scheme="oneway", oneway=setup)
    assert opts.oneway.setup == setup and opts.oneway.kwargs() == setup.kwargs()
    assert opts.oneway.kwargs()["tx_ids"] == [1, 2]


def test_cli_refuses_options_of_another_scheme(recs):
    res = run(["range", "--scheme", "echo", recs["echo"], "--latency", 0.1, "--no-setup"])
    assert_error(res, 2, "--latency", "oneway")
    res = run(["range", "--scheme", "oneway", recs["ow"], "--freq", 1000, "--no-setup"])
    assert_error(res, 2, "--freq", "beepbeep")


def test_loading_plot_does_not_import_ranging():
    """The help texts read the library defaults only when help is shown (LazyHelpOption):
    ``rangekit plot`` loads no ranging code (it did, 0.3 s, when they were read at import)."""
    import subprocess
    import sys

    code = "import sys, rangekit_cli.plot_cmd; print('rangekit.ranging' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False"]


def test_temperature_and_clock_ppm_defaults_are_the_librarys(monkeypatch):
    """--temperature and --clock-ppm read rangekit.physics.DEFAULT_TEMP_C and
    rangekit.ranging.beepbeep.DEFAULT_CLOCK_PPM when the command runs or shows help."""
    import rangekit.physics
    import rangekit.ranging.beepbeep

    monkeypatch.setattr(rangekit.physics, "DEFAULT_TEMP_C", 21.5)
    monkeypatch.setattr(rangekit.ranging.beepbeep, "DEFAULT_CLOCK_PPM", 31.5)
    text = " ".join(ok(run(["range", "--help"])).stdout.split())
    assert "Air temperature, C. [default: 21.5;" in text and "[default: 31.5;" in text
    # A run uses them: calibrate's --verbose names c before it reads the (missing) file.
    r = run(["calibrate", "--scheme", "oneway", "-v", "--distance", 1, "none.wav", "-o", "c.json"])
    assert f"c = {rangekit.physics.speed_of_sound_m_s(21.5):.2f} m/s" in r.stderr


def test_beep_option_help_reads_the_beep_defaults(monkeypatch):
    """The beep options' help shows :class:`rangekit.signals.Beep`'s defaults (read when
    help is shown), not copies."""
    from dataclasses import dataclass

    import rangekit.signals

    @dataclass(frozen=True)
    class Beep(rangekit.signals.Beep):
        f_hz: float = 17500.0
        taper: int = 30

    monkeypatch.setattr(rangekit.signals, "Beep", Beep)
    text = " ".join(ok(run(["range", "--help"])).stdout.split())
    assert "Beep frequency in Hz [default: 17500]" in text
    assert "Raised-cosine taper samples at each end [default: 30]" in text
    assert "Samples per burst [default: 441]" in text
