"""One-way / echo configuration objects from plain values
(``rangekit.ranging.ultrasonic_setup``): only the values given differ from the library's
defaults, and ``q`` means the same as ``--transducer-q``."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rangekit.errors import InvalidParameterError
from rangekit.ranging.config import Detection, EchoSetup, OneWaySetup
from rangekit.ranging.ultrasonic_setup import BURST_FS, scheme_burst, ultrasonic_setup
from rangekit.signals.barker import BARKER_CODES, srf02_ping
from rangekit.signals.transducer import Transducer


@pytest.mark.parametrize("scheme, kind", [("oneway", OneWaySetup), ("echo", EchoSetup)])
def test_nothing_given_is_the_default_object(scheme, kind):
    # Only the burst's rate differs: BURST_FS, replaced by each recording's.
    assert ultrasonic_setup(scheme) == replace(kind(), burst=kind().burst.with_fs(BURST_FS))
    assert scheme_burst(scheme) == kind().burst.with_fs(BURST_FS)


def test_the_burst_takes_the_values_given():
    b = scheme_burst("oneway", code="13", carrier_hz=50000.0, cycles_per_bit=2)
    assert (b.code, b.carrier_hz, b.cycles_per_bit) == (BARKER_CODES[13], 50000.0, 2)
    assert b.amplitude == OneWaySetup().burst.amplitude and b.fs == BURST_FS
    # echo's base is the SRF02 ping; chips may be given as a sequence too.
    e = scheme_burst("echo", code=(1, -1), fs=192000.0)
    assert e == replace(srf02_ping(), code=(1, -1))
    # The deferred rate lets a carrier above a sound card's Nyquist frequency through.
    assert scheme_burst("oneway", carrier_hz=200000.0).carrier_hz == 200000.0


@pytest.mark.parametrize(
    "q, transducer, fit",
    [
        (None, Transducer(), True),  # the library's default: fitted from Q 4
        ("auto", Transducer(), True),
        (0, None, False),  # the bare drive
        (0.0, None, False),
        (6.5, Transducer(q=6.5), False),  # known: folded into the template
    ],
)
def test_q_means_what_transducer_q_means(q, transducer, fit):
    ow = ultrasonic_setup("oneway", q=q)
    assert (ow.transducer, ow.fit_transducers) == (transducer, fit)
    ec = ultrasonic_setup("echo", q=q)
    assert (ec.transducer, ec.fit_transducer) == (transducer, fit)


def test_every_value_reaches_the_object():
    det = Detection(k_noise=5.0)
    s = ultrasonic_setup(
        "oneway", code="+-+", latency_s=0.002, period_s=0.2, tx_ids=[3, 1], channels=4,
        min_range_m=0.5, max_range_m=9.0, detection=det,
    )  # fmt: skip
    assert s == OneWaySetup(
        burst=replace(OneWaySetup().burst, code=(1, -1, 1), fs=BURST_FS), latency_s=0.002,
        period_s=0.2, tx_ids=(3, 1), channels=4, min_range_m=0.5, max_range_m=9.0,
        detection=det,
    )  # fmt: skip
    e = ultrasonic_setup("echo", period_s=0.07, channels=2, max_range_m=3.0)
    assert (e.period_s, e.channels, e.max_range_m) == (0.07, 2, 3.0)
    assert e.min_range_m == EchoSetup().min_range_m


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: ultrasonic_setup("echo", latency_s=0.0), "latency_s applies to scheme 'oneway'"),
        (lambda: ultrasonic_setup("echo", tx_ids=[0]), "tx_ids applies to scheme 'oneway'"),
        (lambda: ultrasonic_setup("beepbeep"), "scheme='beepbeep' must be one of oneway, echo"),
        (lambda: ultrasonic_setup("oneway", code="9"), "no Barker code of length 9"),
        (lambda: ultrasonic_setup("oneway", q=0.2), "q=0.2"),  # below Transducer's 0.5
        (lambda: ultrasonic_setup("oneway", tx_ids=[1.5]), "tx_ids"),
        (lambda: ultrasonic_setup("echo", min_range_m=4.0, max_range_m=2.0), "max_range_m"),
    ],
)
def test_bad_values_are_refused_naming_them(call, match):
    with pytest.raises(InvalidParameterError, match=match):
        call()
