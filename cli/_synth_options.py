"""Options and helpers shared by the ``rangekit synth`` commands."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    LazyHelpOption,
    check_outputs,
    debug_option,
    detail,
    float_list,
    temperature_option,
    transducer_q_options,
    verbosity_options,
)
from rangekit_cli._options_types import library_default


def _impair_spec(ctx, param, value):
    """--impair SPEC parsed now, before anything is rendered or written."""
    if value is None:
        return None
    from rangekit.errors import InvalidParameterError
    from rangekit.sim.impair import parse_impairments

    try:
        return parse_impairments(value)
    except InvalidParameterError as e:
        raise click.BadParameter(str(e), ctx=ctx, param=param) from None


impair_option = click.option(
    "--impair",
    "impairments",
    metavar="SPEC",
    default=None,
    callback=_impair_spec,
    help="Impair the rendered recording before writing it: KEY=VALUE[,...] with keys dc, "
    "clip_db, lf_db, hum_db, hum_hz, pink_db, interference (speech|music), interference_db, "
    "interference_max_hz, agc_db, agc_steps, silence_s, lp_hz, hp_hz; levels in dB over "
    "the rendered noise floor (impairments.md of the documentation).",
)


def write(syn, output: str) -> None:
    """Check every file ``syn`` (a :class:`rangekit.sim.scenarios.Synthesis`) writes
    against the command's inputs, then write them."""
    check_outputs(syn.paths(output))
    syn.write(output)


def parse_point(text: str, name: str) -> list[float]:
    v = float_list(text, name=name)
    if v is None or len(v) != 3:
        raise click.BadParameter(f"{text!r} must be X,Y,Z in metres", param_hint=name)
    return v


def describe_seed(seed) -> None:
    """--verbose: the seed of the noise and draws (none: a fresh one, not reproducible)."""
    what = f"seed {seed}" if seed is not None else "no --seed: fresh randomness, not reproducible"
    detail(f"rangekit: synth: {what}")


def parse_pose(text: str, name: str = "--pose") -> list[float]:
    v = float_list(text, name=name)
    if v is None or len(v) != 3:
        raise click.BadParameter(f"{text!r} must be X,Y,HEADING (m, m, degrees)", param_hint=name)
    return v


def scenario_default(func: str, name: str, convert=None) -> dict:
    """``default``, ``show_default`` and ``cls`` of an option whose default is keyword
    ``name`` of :mod:`rangekit.sim.scenarios`' function ``func`` (``func="ShoeboxRoom"``:
    a field of :class:`rangekit.sim.ShoeboxRoom`), read when the command runs or shows
    help (:class:`LazyHelpOption`), not copied; ``convert`` maps it to the option's unit."""

    path = "rangekit.sim:ShoeboxRoom" if func == "ShoeboxRoom" else f"rangekit.sim.scenarios:{func}"

    def read():
        value = library_default(path, name)
        return value if convert is None else convert(value)

    return {"default": read, "show_default": True, "cls": LazyHelpOption}


def ultrasonic_synth_options(func: str):
    """--temperature, --transducer-q, --fs, --seed, -o, -q/-v and --debug of the ultrasonic
    synth command that calls ``func`` of :mod:`rangekit.sim.scenarios` (its defaults)."""
    q = scenario_default(func, "q")["default"]
    opts = [
        transducer_q_options(
            FiniteRange(0.5, 100.0),
            q,
            lambda: "Q of the transducers (Tx and Rx; the echo sensor has one).",
        ),
        click.option(
            "--fs",
            type=FiniteRange(1000.0, 1e7),
            help="Sample rate, Hz.",
            **scenario_default(func, "fs"),
        ),
        click.option(
            "--seed", type=click.IntRange(0, 2**63 - 1), default=None, help="Random seed, >= 0."
        ),
        click.option("--no-noise", is_flag=True, help="Render without noise."),
        impair_option,
        click.option(
            "-o",
            "--output",
            type=click.Path(dir_okay=False),
            required=True,
            help="WAV file to write.",
        ),
    ]

    def deco(f):
        for o in reversed(opts):
            f = o(f)
        return verbosity_options(debug_option(temperature_option(f)))

    return deco
