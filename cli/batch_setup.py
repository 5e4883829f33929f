"""``rangekit batch``: its options as one :class:`rangekit.batch.BatchOptions` (the
two-way options, and the one-way and echo setups with the probe and calibration), and the
``--verbose`` summary of what was chosen."""

from __future__ import annotations

from dataclasses import replace

from rangekit_cli._options import float_list, make_beep
from rangekit_cli.ultrasonic_options import refuse_ultrasonic_options, ultrasonic_setup

SCHEMES = ("oneway", "echo")  # the ultrasonic schemes, each with its setup


def batch_options(
    scheme,
    pair_by_name,
    self_distance,
    temp_c,
    speed,
    clock_ppm,
    detector,
    template,
    calibration,
    kw,
):
    """The :class:`rangekit.batch.BatchOptions` of ``batch``'s parsed options (``kw``: the
    beep and ultrasonic options); usage errors for options of another scheme."""
    from rangekit.batch import BatchOptions
    from rangekit.ranging.config import Medium

    sd = float_list(self_distance, name="--self-distance", lo=0.0, hi=2.0)
    if scheme == "beepbeep":
        refuse_ultrasonic_options(kw, remove=False)
        beepbeep = {
            "beep": make_beep(kw),
            "detector": detector,
            "temp_c": temp_c,
            "speed_m_s": speed,
            "self_distance_m": _self_distance(sd),
            "clock_ppm": clock_ppm,
        }
    else:
        beepbeep = {"detector": detector, "temp_c": temp_c, "speed_m_s": speed}
    # The options describe sessions of --scheme; sessions whose sidecar names another
    # ultrasonic scheme get that scheme's defaults (and their sidecar's values).
    # A lab's probe: any number of receivers (unless --channels names them).
    setups = {
        s: ultrasonic_setup(kw if s == scheme else {}, scheme=s, any_receivers=template is not None)
        for s in SCHEMES
    }
    ultra = _probe_and_calibration(template, calibration, scheme, sd, kw, beepbeep, setups)
    for s in ultra:
        ultra[s] = replace(ultra[s], medium=Medium(temp_c=temp_c, speed_m_s=speed))
    return BatchOptions(scheme=scheme, beepbeep=beepbeep, pair_by_name=pair_by_name, **ultra)


def details(options, sessions, output) -> None:
    """With --verbose: what was chosen (stderr), before the progress, as the library says
    it (:func:`rangekit.io.notes.batch_details`)."""
    from rangekit_cli._options import detail

    from rangekit.io.notes import batch_details

    for line in batch_details(options, sessions, output):
        detail(f"batch: {line}")


def _probe_and_calibration(template, calibration, scheme, sd, kw, beepbeep, setups) -> dict:
    """Put ``--template`` and ``--calibration`` into the sessions' ranging options:
    into ``beepbeep`` (a dict), and the :class:`rangekit.batch.UltrasonicOptions` of each
    ultrasonic scheme from its ``setups`` (returned, by scheme)."""
    from rangekit_cli._options import load_template, read_calibration, refuse_self_distance

    from rangekit.batch import UltrasonicOptions

    ultra = {s: UltrasonicOptions(setup=v) for s, v in setups.items()}
    probe = load_template(template)
    if probe is not None:
        beepbeep["probe"] = probe
        for s, v in setups.items():
            ultra[s] = UltrasonicOptions(setup=v, probe=probe)
    cal = read_calibration(calibration, scheme)
    if cal is not None:
        if scheme == "beepbeep":
            refuse_self_distance(sd)
            beepbeep["calibration"] = cal
        else:
            ultra[scheme] = replace(ultra[scheme], calibration=cal)
    return ultra


def _self_distance(sd: list[float] | None) -> float | list[float]:
    """--self-distance as the two-way option; not given: the library's default
    (:class:`rangekit.ranging.config.TwoWaySetup`), recorded as such in the results."""
    from rangekit.ranging.config import TwoWaySetup

    if sd is None:
        return TwoWaySetup().self_distance_m
    return sd[0] if len(sd) == 1 else sd
