"""``range_series_beepbeep(jobs=N)``: blocks detected in parallel, the same result as one job."""

from __future__ import annotations

import pytest

from rangekit.errors import InvalidParameterError
from rangekit.io.audio import write_audio
from rangekit.ranging.series import range_series_beepbeep
from rangekit.signals import Beep
from rangekit.sim import ShoeboxRoom, pair_devices
from rangekit.sim.exchanges import render_exchanges

FS = 44100.0


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    """10 exchanges 1.3 s apart (room, 40 ppm skew, jittered gaps), one mono file each."""
    devs = pair_devices(
        2.5, self_distance_m=0.1, center_m=(3.0, 2.5, 1.2), rec_start_s=(0.0, 0.03),
        clock_ppm=(0.0, 40.0),
    )  # fmt: skip
    sim = render_exchanges(
        devs,
        source=Beep().samples_at(FS),
        source_fs=FS,
        n_exchanges=10,
        period_s=1.3,
        jitter_s=0.1,
        room=ShoeboxRoom((6.0, 5.0, 3.0), absorption=0.3, max_order=2),
        snr_db=15.0,
        rng=7,
    )
    d = tmp_path_factory.mktemp("series")
    paths = [d / f"dev{i}.wav" for i in range(2)]
    for p, x in zip(paths, sim.recordings, strict=True):
        write_audio(p, x, fs=FS)
    return paths


def _rows(ex):
    return [
        (e.exchange, e.t_s, e.error, r.a, r.b, r.distance_m, r.sigma_m, r.flags)
        for e in ex
        for r in e.ranges
    ]


@pytest.mark.parametrize("detector", ["changepoint", "xcorr"])
def test_jobs_give_the_same_series(series, detector):
    # 1.7 s blocks: most exchanges' beeps straddle a block boundary somewhere.
    kw = {"self_distance_m": 0.1, "block_s": 1.7, "detector": detector}
    one = list(range_series_beepbeep(series, **kw))
    two = list(range_series_beepbeep(series, jobs=2, **kw))
    assert len(one) == 10 and all(e.error is None for e in one)
    assert _rows(two) == _rows(one)  # exactly: the grouping is serial, detection per block
    for e in one:
        r = e.ranges[0]
        # changepoint: uncorrected 40 ppm skew, a few mm. The xcorr baseline takes a
        # reflection 0.92 m late here, and says so.
        assert abs(r.distance_m - 2.5) < 0.03 or "ambiguous_first_path" in r.flags, r
    if detector == "changepoint":
        assert all(abs(e.ranges[0].distance_m - 2.5) < 0.03 for e in one)


def test_progress_and_bad_jobs(series):
    seen = []
    ex = list(range_series_beepbeep(series, self_distance_m=0.1, block_s=4.0, jobs=3,
                                    progress=lambda d, t: seen.append((d, t))))  # fmt: skip
    assert len(ex) == 10
    assert [round(d, 6) for d, _ in seen] == sorted(round(d, 6) for d, _ in seen)
    assert seen[-1][0] == pytest.approx(seen[-1][1])
    with pytest.raises(InvalidParameterError, match="jobs"):
        range_series_beepbeep(series, jobs=0)
