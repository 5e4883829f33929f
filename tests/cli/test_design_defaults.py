"""``rangekit design`` restates no default of the library: the help's defaults of the
Barker burst, the sweep and the beep's rate are read from :class:`CodedBurst`,
:func:`linear_sweep` / ``DEFAULT_FADE_S`` and :class:`Beep` when help is shown (issue 19:
"library defaults are copied into the CLI")."""

from __future__ import annotations

from dataclasses import dataclass

from clihelp import ok, run, with_defaults

import rangekit.signals
from rangekit.signals import barker, probe
from rangekit.signals.barker import BARKER_CODES


def _help(*cmd) -> str:
    return " ".join(ok(run(["design", *cmd, "--help"])).stdout.split())


def test_the_help_shows_the_librarys_defaults(monkeypatch):
    @dataclass(frozen=True)
    class Burst(barker.CodedBurst):
        code: tuple[int, ...] = BARKER_CODES[13]
        carrier_hz: float = 25000.0
        cycles_per_bit: int = 5
        fs: float = 96000.0

    @dataclass(frozen=True)
    class Beep(rangekit.signals.Beep):
        fs: float = 48000.0

    monkeypatch.setattr(barker, "CodedBurst", Burst)
    monkeypatch.setattr(rangekit.signals, "Beep", Beep)
    monkeypatch.setattr(probe, "linear_sweep", with_defaults(probe.linear_sweep, fs=64000.0))
    monkeypatch.setattr(probe, "DEFAULT_FADE_S", 0.01)
    text = _help("barker")
    for shown in ("as + and - [default: 13].", "Carrier, Hz [default: 25000].",
                  "per chip [default: 5].", "main lobe. [default: 96000.0;"):  # fmt: skip
        assert shown in text, shown
    assert "the beep's, 48000]." in _help("beep")
    text = _help("sweep")
    assert "fs / 2. [default: 64000.0;" in text
    assert "[default: min(0.01, duration / 10)]." in text


def test_a_barker_file_uses_the_librarys_rate(tmp_path):
    import soundfile as sf

    out = tmp_path / "b.wav"
    ok(run(["design", "barker", "-q", "-o", out]))
    assert sf.info(str(out)).samplerate == barker.CodedBurst().fs == 192000.0
