"""``rangekit.ranging.run`` without audio: the counting, withholding and reporting of
:class:`SeriesRows` and :class:`RangeRun`, the clock-rate lines, and the job's checks of
its options (issue 21: the mutation check of the module; the audio paths are in
``tests/cli/test_range_library.py``). Runs in well under a second.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest

from rangekit.errors import DetectionError, InvalidParameterError, UnreliableResultError
from rangekit.ranging import run as R
from rangekit.ranging.clock import ClockRates
from rangekit.ranging.config import EchoSetup, OneWaySetup, SeriesOptions


@dataclass
class _Exchange:
    """What SeriesRows reads of a two-way series item."""

    out: list
    error: str | None = None

    def rows(self):
        return [dict(r) for r in self.out]


@dataclass
class _Window:
    out: list

    def rows(self, *, scheme):
        assert scheme in ("oneway", "echo")
        return [dict(r) for r in self.out]


def _row(d=2.0, flags=(), **kw):
    return {"t_s": 1.5, "a": 0, "b": 1, "distance_m": d, "sigma_m": 0.01, "flags": list(flags),
            **kw}  # fmt: skip


def test_clock_rate_correction_keeps_rates_as_floats():
    c = R.ClockRateCorrection(ppm=[80, np.float32(1.5)])
    assert c.ppm == (80.0, 1.5) and all(type(v) is float for v in c.ppm)
    assert R.ClockRateCorrection().ppm is None
    with pytest.raises(dataclasses.FrozenInstanceError):  # built once, checked once
        c.ppm = (1.0,)


def test_series_rows_two_way_counts_failed_exchanges():
    items = [_Exchange([_row()]), _Exchange([_row(None)], error="no beep in 'a'"),
             _Exchange([_row(), _row(3.0)]), _Exchange([_row(None)], error="second")]  # fmt: skip
    rows = R.SeriesRows(items, scheme="beepbeep")
    blocks = list(rows)
    assert [len(b) for b in blocks] == [1, 1, 2, 1]
    assert (rows.n_items, rows.n_bad, rows.n_rows) == (4, 2, 5)
    assert rows.first_error == "no beep in 'a'"  # the first, not the last
    assert rows.warnings() == [
        "rangekit: 2 of 4 exchanges failed detection (empty distance, flag 'detection'); "
        "first: no beep in 'a'"
    ]
    assert rows.withheld == []  # not strict


def test_series_rows_without_failures_warns_nothing():
    rows = R.SeriesRows([_Exchange([_row()])], scheme="beepbeep")
    list(rows)
    assert rows.warnings() == [] and rows.first_error is None and rows.n_bad == 0
    w = R.SeriesRows([_Window([_row()])], scheme="oneway")
    list(w)
    assert w.warnings() == []


def test_series_rows_windows_count_rows_without_a_distance():
    items = [_Window([_row(), _row(None), _row(None)]), _Window([_row(1.0)])]
    rows = R.SeriesRows(items, scheme="echo")
    assert [len(b) for b in rows] == [3, 1]
    assert (rows.n_items, rows.n_bad, rows.n_rows) == (0, 2, 4)
    assert rows.warnings() == [
        "rangekit: 2 of 4 (window, channel) rows without a detection (empty distance: "
        "nothing in range)"
    ]


def test_series_rows_strict_withholds_only_doubtful_rows():
    items = [_Exchange([_row(), _row(flags=["clipped"])]), _Exchange([_row(flags=["low_snr"])])]
    rows = R.SeriesRows(items, scheme="beepbeep", strict=True)
    out = [r for b in rows for r in b]
    assert [r["distance_m"] for r in out] == [2.0, None, None]
    assert len(rows.withheld) == 2 and rows.withheld[0] is out[1]
    assert out[1]["flags"] == ["clipped", "withheld"]
    lax = R.SeriesRows([_Exchange([_row(flags=["clipped"])])], scheme="beepbeep")
    assert [r["distance_m"] for b in lax for r in b] == [2.0] and lax.withheld == []


def _run(rows_obj=None, withheld=(), n_rows=0, blocks=()):
    return R.RangeRun("beepbeep", rows_obj is not None, ("a",), {}, ("x.wav", "y.wav"),
                      blocks if rows_obj is None else rows_obj, rows_obj, list(withheld),
                      n_rows)  # fmt: skip


def test_range_run_rows_and_warnings():
    run = _run(blocks=[[{"a": 1}], [], [{"a": 2}, {"a": 3}]])
    assert run.rows() == [{"a": 1}, {"a": 2}, {"a": 3}]
    assert run.warnings() == []
    run.finish()  # nothing withheld: no error
    s = R.SeriesRows([_Exchange([_row(None)], error="boom")], scheme="beepbeep")
    run = _run(s)
    assert len(run.rows()) == 1 and run.warnings() == s.warnings() != []


def test_range_run_repr_leaves_out_its_rows():
    """A series' run holds a generator and may hold thousands of rows: not in its repr."""
    s = R.SeriesRows([_Exchange([_row()])], scheme="beepbeep")
    run = _run(s, withheld=[_row(9.0)])
    text = repr(run)
    assert text.startswith("RangeRun(scheme='beepbeep', series=True")
    assert "_blocks=" not in text and " _rows=" not in text and "_withheld=" not in text
    assert "SeriesRows" not in text and "9.0" not in text


def test_finish_raises_naming_inputs_count_and_first_row():
    r = _row(3.0, flags=["clipped", "low_snr"])
    r.update(distance_m=None, sigma_m=None, flags=["clipped", "low_snr", "withheld"])
    run = _run(withheld=[r, _row()], n_rows=7)
    with pytest.raises(UnreliableResultError) as e:
        run.finish()
    assert str(e.value) == (
        "strict: x.wav, y.wav: 2 of 7 ranges withheld as doubtful (written with an empty "
        "distance, flag 'withheld'); first: t_s 1.5, a 0, b 1 flagged clipped,low_snr"
    )
    # a series: the counts are the SeriesRows'; keys that are None are left out
    items = [_Exchange([_row()]), _Exchange([_row(flags=["clipped"], a=None, window=4)])]
    s = R.SeriesRows(items, scheme="beepbeep", strict=True)
    run = _run(s)
    run.rows()
    with pytest.raises(UnreliableResultError, match=r"1 of 2 ranges .* first: t_s 1.5, b 1, "
                       r"window 4 flagged clipped$"):  # fmt: skip
        run.finish()


def test_clock_rate_lines():
    rates = ClockRates(np.array([0.0, 79.2, -3.0]), np.array([0.0, 0.11, 0.5]), 4, 4.5)
    assert R.clock_rate_lines(rates) == [
        "rangekit: clock rate vs device 0: device 1 +79.20 +- 0.11 ppm (4 exchanges over 4.5 s)",
        "rangekit: clock rate vs device 0: device 2 -3.00 +- 0.50 ppm (4 exchanges over 4.5 s)",
    ]
    rates = ClockRates(np.array([0.0, 1.0]), np.array([0.0, 0.2]), 9, 12.0, n_rejected=2)
    assert R.clock_rate_lines(rates) == [
        "rangekit: clock rate vs device 0: device 1 +1.00 +- 0.20 ppm (9 exchanges over 12.0 s,"
        " 2 rejected)"
    ]


def test_ultrasonic_kwargs_by_scheme():
    assert R._ultrasonic_kwargs("oneway", None) == OneWaySetup().kwargs()
    assert R._ultrasonic_kwargs("echo", None) == EchoSetup().kwargs()
    cfg = OneWaySetup(max_range_m=4.0)
    assert R._ultrasonic_kwargs("oneway", cfg) == cfg.kwargs()
    m = {"period_s": 0.2}
    got = R._ultrasonic_kwargs("echo", m)
    assert got == m and got is not m
    with pytest.raises(InvalidParameterError, match="does not describe scheme='echo'"):
        R._ultrasonic_kwargs("echo", OneWaySetup())
    with pytest.raises(InvalidParameterError, match="give a OneWaySetup"):
        R._ultrasonic_kwargs("oneway", EchoSetup())


@pytest.mark.parametrize(
    ("kw", "match"),
    [({"scheme": "radar"}, "scheme='radar'"),
     ({"scheme": "oneway", "clock_rate": R.ClockRateCorrection()}, "two-way"),
     ({"scheme": "echo", "series": SeriesOptions()}, "needs period_s"),
     ({"scheme": "echo", "series": SeriesOptions(), "ultrasonic": {"period_s": 0.07},
       "files": ["a.wav", "b.wav"]}, "takes one file, got 2"),
     ({"scheme": "oneway", "series": SeriesOptions(), "probe": object()}, "two-way"),
     ({"clock_rate": R.ClockRateCorrection()}, "two-way series only")],
)  # fmt: skip
def test_run_range_checks_options_before_reading(kw, match):
    files = kw.pop("files", ["missing.wav"])
    with pytest.raises(InvalidParameterError, match=match):
        R.run_range(files, **kw)


def test_echo_series_through_run_range(tmp_path):
    """An ultrasonic series: the rows are range_series_ultrasonic's, the job's metadata
    says series, and a cycle without an echo is counted in the warnings."""
    import soundfile as sf

    from rangekit.floorplan import FloorPlan
    from rangekit.ranging.series import SERIES_FIELDS, range_series_ultrasonic
    from rangekit.sim.ultrasonic import render_echo

    plan = FloorPlan.from_walls([((1.5, -5), (1.5, 5)), ((-9, -5), (-9, 5))])
    cyc = render_echo(plan, [(0.0, 0.0, 0.0)], snr_db=None).x[0][:13440]
    x = np.tile(0.5 * cyc / np.max(np.abs(cyc)), 3)
    x += 1e-3 * np.random.default_rng(5).standard_normal(len(x))
    x[13440 + 1000 : 13440 + 9000] = 1e-3 * np.random.default_rng(6).standard_normal(8000)
    path = tmp_path / "echo.wav"
    sf.write(path, x, 192000, "PCM_16")
    kw = {"period_s": 0.07, "pool": False}
    run = R.run_range([path], scheme="echo", series=SeriesOptions(), ultrasonic=kw)
    assert run.series and run.fields == SERIES_FIELDS["echo"]
    assert run.meta == {"scheme": "echo", "series": True, "files": [str(path)]}
    rows = run.rows()
    want = [r for w in range_series_ultrasonic(path, scheme="echo", **kw)
            for r in w.rows(scheme="echo")]  # fmt: skip
    assert rows == want and len(rows) == 3 and rows[1]["distance_m"] is None
    assert run.warnings() == [
        "rangekit: 1 of 3 (window, channel) rows without a detection (empty distance: "
        "nothing in range)"
    ]
    # the same file, not as a series: the whole-file rows, series False
    whole = R.run_range([path], scheme="echo", ultrasonic=kw)
    assert not whole.series and whole.meta == {"scheme": "echo", "files": [str(path)]}
    assert [r["distance_m"] for r in whole.rows()] == [r["distance_m"] for r in rows]


def test_two_way_series_through_run_range(tmp_path):
    import soundfile as sf

    from rangekit.physics import Medium
    from rangekit.ranging.config import TwoWaySetup
    from rangekit.ranging.series import SERIES_FIELDS
    from rangekit.sim.recording import pair_devices, render_beepbeep

    sim = render_beepbeep(pair_devices(2.0, self_distance_m=0.1), snr_db=30.0, rng=3)
    one = np.stack(sim.recordings, axis=1)
    x = np.concatenate([np.pad(one, ((0, 2 * 44100 - len(one)), (0, 0)))] * 2)
    path = tmp_path / "two.wav"
    sf.write(path, x, 44100, "PCM_16")
    run = R.run_range([path], setup=TwoWaySetup(0.1), series=SeriesOptions())
    assert run.series and run.fields == SERIES_FIELDS["beepbeep"]
    rows = run.rows()
    assert [round(r["distance_m"], 2) for r in rows] == [2.0, 2.0]
    assert run.meta["series"] is True and run.meta["detector"] == "changepoint"
    assert run.meta["files"] == [str(path)] and run.meta["speed_of_sound_m_s"] == Medium().c
    given = R.run_range([path], setup=TwoWaySetup(0.1), series=SeriesOptions(),
                        clock_rate=R.ClockRateCorrection(ppm=(0.0,)))  # fmt: skip
    assert [r["distance_m"] for r in given.rows()] == pytest.approx([r["distance_m"] for r in rows])
    assert given.meta["clock_rate"]["mode"] == "given"
    with pytest.raises(DetectionError, match="is this one exchange"):  # not as a series
        R.run_range([path], setup=TwoWaySetup(0.1))
