"""The ultrasonic options become the library's objects through one call: the CLI's
``ultrasonic_setup`` equals :func:`rangekit.ranging.ultrasonic_setup.ultrasonic_setup`
of the same values, and ``--code`` errors stay usage errors naming the option."""

from __future__ import annotations

import click
import pytest
from rangekit_cli.ultrasonic_options import ULTRASONIC_KEYS, ultrasonic_setup

from rangekit.ranging.ultrasonic_setup import ultrasonic_setup as library_setup


@pytest.mark.parametrize(
    "scheme, kw, values",
    [
        ("oneway", {}, {}),
        ("echo", {}, {}),
        (
            "oneway",
            {"code": "5", "carrier": 41000.0, "cycles_per_bit": 4, "q": "auto",
             "latency": 0.003, "period": 0.2, "tx_order": "2,0,1", "channels": 3,
             "min_range": 0.2, "max_range": 12.0},
            {"code": (1, 1, 1, -1, 1), "carrier_hz": 41000.0, "cycles_per_bit": 4,
             "q": "auto", "latency_s": 0.003, "period_s": 0.2, "tx_ids": (2, 0, 1),
             "channels": 3, "min_range_m": 0.2, "max_range_m": 12.0},
        ),
        ("echo", {"code": "++-", "q": 0.0, "period": 0.07},
         {"code": "++-", "q": 0, "period_s": 0.07}),
        ("oneway", {"q": 7.0, "tx_order": "4"}, {"q": 7.0, "tx_ids": [4]}),
    ],
)  # fmt: skip
def test_cli_setup_is_the_library_call(scheme, kw, values):
    full = dict.fromkeys(ULTRASONIC_KEYS) | kw  # as click passes them: None when not given
    assert ultrasonic_setup(full, scheme=scheme) == library_setup(scheme, **values)


def test_code_and_tx_order_errors_name_the_option():
    with pytest.raises(click.BadParameter) as e:
        ultrasonic_setup({"code": "6"}, scheme="oneway")
    assert e.value.param_hint == "--code" and "no Barker code of length 6" in e.value.message
    with pytest.raises(click.BadParameter) as e:
        ultrasonic_setup({"tx_order": "1,2.5"}, scheme="oneway")
    assert e.value.param_hint == "--tx-order" and "whole numbers" in e.value.message
    with pytest.raises(click.UsageError, match="--tx-order applies to --scheme oneway only"):
        ultrasonic_setup({"tx_order": "1"}, scheme="echo")


@pytest.mark.parametrize("scheme", ["oneway", "echo"])
def test_any_receivers_unless_channels_names_them(scheme):
    """A lab's probe or a calibration rig (``any_receivers``): the setup takes as many
    receivers as the recordings hold (``channels=None``) unless ``--channels`` is given;
    without ``any_receivers`` the library's default stands. ``range``, ``calibrate`` and
    ``batch`` (every scheme's setup, with ``--template``) apply this one rule."""
    full = dict.fromkeys(ULTRASONIC_KEYS)
    default = library_setup(scheme).channels  # one-way: a number; echo: None already
    assert (default is None) == (scheme == "echo")
    assert ultrasonic_setup(full, scheme=scheme).channels == default
    assert ultrasonic_setup(full, scheme=scheme, any_receivers=True).channels is None
    named = full | {"channels": 2}
    assert ultrasonic_setup(named, scheme=scheme, any_receivers=True).channels == 2


def test_batch_with_a_template_opens_every_schemes_receivers(tmp_path):
    """``batch --template``: the sessions' one-way and echo setups take any receivers,
    except the command's own scheme when ``--channels`` names them; without a template
    ``--channels`` and the defaults stand."""
    import numpy as np
    import soundfile as sf
    from rangekit_cli.batch_setup import batch_options

    t = np.arange(2205) / 44100.0
    sf.write(tmp_path / "sweep.wav", 0.5 * np.sin(2 * np.pi * (17000 + 15000 * t) * t), 44100)
    kw = dict.fromkeys(ULTRASONIC_KEYS) | {"channels": 2}
    args = ("echo", False, None, 20.0, None, 30.0, "changepoint")  # the command's scheme: echo
    plain = batch_options(*args, None, None, dict(kw))
    default = library_setup("oneway").channels
    assert default is not None
    assert plain.echo.setup.channels == 2 and plain.oneway.setup.channels == default
    probed = batch_options(*args, str(tmp_path / "sweep.wav"), None, dict(kw))
    assert probed.echo.setup.channels == 2 and probed.oneway.setup.channels is None
    assert probed.echo.probe is not None and probed.oneway.probe is not None
    kw["channels"] = None
    assert batch_options(*args, str(tmp_path / "sweep.wav"), None, kw).echo.setup.channels is None
