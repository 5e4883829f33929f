"""``rangekit.ranging.config``: each configuration object accepts its documented domain,
rejects what lies outside it before any recording is read, and hands the keyword APIs
exactly the library's defaults (issue 21: the mutation check of the module). Runs in well
under a second.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from rangekit.errors import IncompatibleInputError, InvalidParameterError
from rangekit.ranging import config as K
from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM
from rangekit.ranging.echo import range_echo
from rangekit.ranging.oneway import range_oneway
from rangekit.ranging.series import DEFAULT_SKEW_S
from rangekit.signals.barker import CodedBurst, srf02_ping
from rangekit.signals.transducer import Transducer


def _defaults(func):
    return {k: p.default for k, p in inspect.signature(func).parameters.items()}


# ---------------------------------------------------------------- TwoWaySetup


def test_two_way_defaults_and_kwargs():
    s = K.TwoWaySetup()
    assert s.self_distance_m == 0.0 and s.clock_ppm == DEFAULT_CLOCK_PPM
    assert s.kwargs() == {"self_distance_m": 0.0, "clock_ppm": DEFAULT_CLOCK_PPM}
    assert s.self_distances(3).tolist() == [0.0, 0.0, 0.0]


def test_two_way_sequence_is_kept_as_tuple_and_given_as_list():
    for sd in ([0.1, 0.12], (0.1, 0.12), np.array([0.1, 0.12])):
        s = K.TwoWaySetup(self_distance_m=sd, clock_ppm=5.0)
        assert s.self_distance_m == (0.1, 0.12) and isinstance(s.self_distance_m, tuple)
        kw = s.kwargs()
        assert kw == {"self_distance_m": [0.1, 0.12], "clock_ppm": 5.0}
        assert isinstance(kw["self_distance_m"], list)
        assert s.self_distances(2).tolist() == [0.1, 0.12]
    # a 0-d array is one value, not a sequence
    s = K.TwoWaySetup(self_distance_m=np.float64(0.2))
    assert s.self_distances(2).tolist() == [0.2, 0.2]
    with pytest.raises(IncompatibleInputError):
        K.TwoWaySetup(self_distance_m=[0.1, 0.12]).self_distances(3)


@pytest.mark.parametrize("ppm", [0.0, 1e4, 20.0])
def test_two_way_clock_domain_edges_accepted(ppm):
    assert K.TwoWaySetup(clock_ppm=ppm).clock_ppm == ppm


@pytest.mark.parametrize(
    "kw",
    [{"clock_ppm": -1e-9}, {"clock_ppm": 1e4 + 1}, {"clock_ppm": np.nan},
     {"self_distance_m": -0.01}, {"self_distance_m": 2.5}, {"self_distance_m": [0.1, 3.0]},
     {"self_distance_m": [0.1, "x"]}, {"self_distance_m": (0.1, None)}],
)  # fmt: skip
def test_two_way_rejects_outside_domain(kw):
    with pytest.raises(InvalidParameterError):
        K.TwoWaySetup(**kw)


# ---------------------------------------------------------------- SeriesOptions


def test_series_defaults():
    s = K.SeriesOptions()
    assert (s.block_s, s.exchange_s, s.skew_s, s.jobs) == (None, None, DEFAULT_SKEW_S, 1)


@pytest.mark.parametrize(
    "kw",
    [{"block_s": 0.001}, {"block_s": 1e6}, {"exchange_s": 0.001}, {"exchange_s": 3600.0},
     {"skew_s": 0.0}, {"skew_s": 3600.0}, {"jobs": 1}, {"jobs": 256}],
)  # fmt: skip
def test_series_domain_edges_accepted(kw):
    s = K.SeriesOptions(**kw)
    ((name, value),) = kw.items()
    assert getattr(s, name) == value


@pytest.mark.parametrize(
    "kw",
    [{"block_s": 0.0009}, {"block_s": 2e6}, {"exchange_s": 0.0}, {"exchange_s": 3601.0},
     {"skew_s": -0.01}, {"skew_s": 4000.0}, {"jobs": 0}, {"jobs": 257}, {"jobs": True},
     {"jobs": 2.0}, {"jobs": "2"}],
)  # fmt: skip
def test_series_rejects_outside_domain(kw):
    with pytest.raises(InvalidParameterError):
        K.SeriesOptions(**kw)


def test_as_self_distance():
    assert K.as_self_distance([0.1]) == 0.1 and isinstance(K.as_self_distance([1]), float)
    assert K.as_self_distance([0.1, 0.2]) == (0.1, 0.2)
    assert K.as_self_distance(np.array([1, 2])) == (1.0, 2.0)


# ---------------------------------------------------------------- Detection


def test_detection_defaults_are_range_oneways():
    d = K.Detection()
    ow = _defaults(range_oneway)
    assert d.kwargs() == {k: ow[k] for k in ("k_noise", "k_detect", "rel_threshold", "block")}


@pytest.mark.parametrize(
    "kw", [{"rel_threshold": 1.0}, {"rel_threshold": 1e-6}, {"block": 16}, {"k_noise": 1e-3}]
)
def test_detection_domain_edges_accepted(kw):
    d = K.Detection(**kw)
    ((name, value),) = kw.items()
    assert getattr(d, name) == value and d.kwargs()[name] == value


@pytest.mark.parametrize(
    "kw",
    [{"k_noise": 0.0}, {"k_detect": 0.0}, {"k_detect": -1.0}, {"rel_threshold": 0.0},
     {"rel_threshold": 1.01}, {"block": 15}, {"block": 64.5}],
)  # fmt: skip
def test_detection_rejects_outside_domain(kw):
    with pytest.raises(InvalidParameterError):
        K.Detection(**kw)


# ---------------------------------------------------------------- OneWaySetup / EchoSetup


def test_oneway_defaults_are_the_librarys_and_reach_the_call():
    ow = _defaults(range_oneway)
    s = K.OneWaySetup()
    kw = s.kwargs()
    assert kw["channels"] == K.ONEWAY_RECEIVERS == 3
    assert kw["burst"] == CodedBurst()
    for ours, theirs in [("tx", "tx"), ("rx", "rx"), ("fit_transducers", "fit_transducers"),
                         ("latency_s", "latency_s"), ("period_s", "period_s"),
                         ("tx_ids", "tx_ids"), ("min_range_m", "min_range_m"),
                         ("max_range_m", "max_range_m"), ("k_noise", "k_noise"),
                         ("k_detect", "k_detect"), ("rel_threshold", "rel_threshold"),
                         ("block", "block")]:  # fmt: skip
        assert kw[ours] == ow[theirs], ours
    assert set(kw) - {"channels", "burst"} <= set(ow)


def test_oneway_values_reach_the_kwargs():
    tr = Transducer(f0_hz=40000.0, q=6.0)
    s = K.OneWaySetup(transducer=tr, fit_transducers=False, latency_s=0.002, period_s=0.1,
                      tx_ids=[2, 0, 1], min_range_m=0.5, max_range_m=4.0, channels=None,
                      detection=K.Detection(block=512))  # fmt: skip
    assert s.tx_ids == (2, 0, 1)
    kw = s.kwargs()
    assert kw["tx"] is tr and kw["rx"] is tr and kw["fit_transducers"] is False
    assert kw["tx_ids"] == [2, 0, 1] and isinstance(kw["tx_ids"], list)
    assert (kw["latency_s"], kw["period_s"], kw["min_range_m"], kw["max_range_m"]) == (
        0.002, 0.1, 0.5, 4.0)  # fmt: skip
    assert kw["channels"] is None and kw["block"] == 512
    assert K.OneWaySetup(tx_ids=(np.int64(0), 1.0)).tx_ids == (0, 1)
    assert K.OneWaySetup(latency_s=0.0).latency_s == 0.0
    assert K.OneWaySetup(latency_s=10.0).latency_s == 10.0


@pytest.mark.parametrize(
    "kw",
    [{"latency_s": -1e-6}, {"latency_s": 10.5}, {"tx_ids": []}, {"tx_ids": [0, -1]},
     {"tx_ids": [0, 1.5]}, {"tx_ids": [True]}, {"burst": "barker"}, {"transducer": 4.0},
     {"period_s": 0.0}, {"period_s": 5000.0}, {"min_range_m": -0.1}, {"max_range_m": 0.0},
     {"min_range_m": 3.0, "max_range_m": 3.0}, {"min_range_m": 4.0, "max_range_m": 3.0},
     {"channels": 0}, {"detection": {"block": 64}}],
)  # fmt: skip
def test_oneway_rejects_outside_domain(kw):
    with pytest.raises(InvalidParameterError):
        K.OneWaySetup(**kw)


def test_oneway_edges_accepted():
    assert K.OneWaySetup(period_s=1e-4).period_s == 1e-4
    assert K.OneWaySetup(period_s=3600.0).period_s == 3600.0
    assert K.OneWaySetup(min_range_m=0.0).min_range_m == 0.0
    assert K.OneWaySetup(channels=1).channels == 1
    assert K.OneWaySetup(transducer=None).kwargs()["tx"] is None


def test_echo_defaults_are_the_librarys_and_reach_the_call():
    ec = _defaults(range_echo)
    s = K.EchoSetup()
    kw = s.kwargs()
    assert kw["burst"] == srf02_ping() and kw["channels"] is None
    for k in ("transducer", "period_s", "min_range_m", "max_range_m", "k_noise", "k_detect",
              "rel_threshold", "block"):  # fmt: skip
        assert kw[k] == ec[k], k
    assert set(kw) - {"channels", "burst"} <= set(ec)
    s = K.EchoSetup(period_s=0.07, min_range_m=0.2, max_range_m=3.0, channels=2)
    kw = s.kwargs()
    assert (kw["period_s"], kw["min_range_m"], kw["max_range_m"], kw["channels"]) == (
        0.07, 0.2, 3.0, 2)  # fmt: skip


@pytest.mark.parametrize(
    "kw",
    [{"min_range_m": 2.0, "max_range_m": 1.0}, {"burst": None}, {"channels": 0},
     {"detection": None}, {"period_s": -1.0}],
)  # fmt: skip
def test_echo_rejects_outside_domain(kw):
    with pytest.raises(InvalidParameterError):
        K.EchoSetup(**kw)


def test_medium_is_physics_medium():
    from rangekit.physics import Medium

    assert K.Medium is Medium


@pytest.mark.parametrize(
    ("make", "attr"),
    [(K.TwoWaySetup, "clock_ppm"), (K.SeriesOptions, "jobs"), (K.Detection, "block"),
     (K.OneWaySetup, "latency_s"), (K.EchoSetup, "max_range_m")],
)  # fmt: skip
def test_configurations_are_frozen_and_hashable(make, attr):
    """Validated once when built: a built object cannot be changed past its checks."""
    import dataclasses

    cfg = make()
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(cfg, attr, -1)
    assert hash(cfg) == hash(make()) and cfg == make()
