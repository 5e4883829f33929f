"""``synth oneway`` / ``synth echo`` restate no default of the simulator: each option's
default is read from :mod:`rangekit.sim.scenarios` (or :class:`rangekit.sim.ShoeboxRoom`)
when help is shown or the command runs (issue 19: "library defaults are copied into the
CLI")."""

from __future__ import annotations

import inspect
import json
import math

from clihelp import ok, run, with_defaults

import rangekit.sim
from rangekit.sim import scenarios


def _help(*cmd) -> str:
    return " ".join(ok(run(["synth", *cmd, "--help"])).stdout.split())


def test_the_help_shows_the_librarys_defaults(monkeypatch):
    ow = with_defaults(scenarios.synth_oneway, ceiling_m=2.5, radius_m=0.3, period_s=0.25,
                        latency_s=0.001, snr_db=15.0, q=6.0, fs=96000.0)  # fmt: skip
    ec = with_defaults(scenarios.synth_echo, mount_angle_rad=math.pi / 2, snr_db=12.0, q=5.0)
    monkeypatch.setattr(scenarios, "synth_oneway", ow)
    monkeypatch.setattr(scenarios, "synth_echo", ec)
    monkeypatch.setattr(rangekit.sim, "ShoeboxRoom", with_defaults(rangekit.sim.ShoeboxRoom,
                        absorption=0.45, max_order=2))  # fmt: skip
    text = _help("oneway")
    for shown in ("§V). [default: 2.5;", "degrees). [default: 0.3;", "(5 Hz). [default: 0.25;",
                  "latency, s. [default: 0.001;", "main lobe). [default: 15.0;",
                  "absorption. [default: 0.45;", "order. [default: 2;", "one). [default: 6.0;",
                  "Hz. [default: 96000.0;"):  # fmt: skip
        assert shown in text, shown
    text = _help("echo")
    for shown in ("= left). [default: 90.0;", "range, dB. [default: 12.0;", "one). [default: 5.0;"):
        assert shown in text, shown


def test_a_run_uses_them(tmp_path):
    out = tmp_path / "ow.wav"
    ok(run(["synth", "oneway", "--no-noise", "--seed", 1, "-o", out]))
    setup = json.loads(out.with_suffix(".json").read_text())["setup"]
    lib = inspect.signature(scenarios.synth_oneway).parameters
    assert setup["period_s"] == lib["period_s"].default == 0.2  # the paper's 5 Hz
    assert setup["latency_s"] == lib["latency_s"].default
    assert setup["tx_order"] == list(range(len(scenarios.DEFAULT_TXS)))  # six transmitters


def test_synth_beepbeep_shows_the_librarys_defaults(monkeypatch):
    """``synth beepbeep``'s --self-distance, --snr-db, --fs, --absorption and --order come
    from :func:`rangekit.sim.scenarios.synth_beepbeep` and :class:`ShoeboxRoom` too."""
    bb = with_defaults(scenarios.synth_beepbeep, self_distance_m=0.15, snr_db=25.0, fs=48000.0)
    monkeypatch.setattr(scenarios, "synth_beepbeep", bb)
    monkeypatch.setattr(rangekit.sim, "ShoeboxRoom", with_defaults(rangekit.sim.ShoeboxRoom,
                        absorption=0.45, max_order=2))  # fmt: skip
    text = _help("beepbeep")
    for shown in ("distance, m. [default: 0.15]", "direct beep, dB. [default: 25.0]",
                  "rate, Hz. [default: 48000.0]", "absorption. [default: 0.45]",
                  "grow as (2 order + 1)^3). [default: 2;"):  # fmt: skip
        assert shown in text, shown
