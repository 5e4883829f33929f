"""Options shared by several commands, and their conversion to library objects."""

from __future__ import annotations

import functools
import math

import click

FORMATS = ("table", "json", "csv")


def shown_default(value) -> str:
    """A default in a help text, the one way every ``--help`` shows them.

    >>> shown_default(0.05), shown_default("no gate")
    ('[default: 0.05]', '[default: no gate]')
    """
    return f"[default: {value:g}]" if isinstance(value, float) else f"[default: {value}]"


def doc_page(name: str) -> str:
    """How a help text names a documentation page (an installed package has no docs/).

    >>> doc_page("rigs.md")
    'rigs.md of the documentation'
    """
    return f"{name} of the documentation"


class FiniteRange(click.FloatRange):
    """click.FloatRange that also refuses NaN (which compares false to every bound)."""

    def convert(self, value, param, ctx):
        v = super().convert(value, param, ctx)
        if not math.isfinite(v):
            self.fail(f"{v} is not a finite number", param, ctx)
        return v


class QOrAuto(click.ParamType):
    """``auto`` or a finite quality factor in [0, 100] (``--transducer-q``)."""

    name = "auto|Q"

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value.strip().lower() == "auto":
            return "auto"
        try:
            v = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is neither 'auto' nor a number", param, ctx)
        if not (math.isfinite(v) and 0.0 <= v <= 100.0):
            self.fail(f"{value!r} is not 'auto' or within [0, 100]", param, ctx)
        return v


class LazyHelpOption(click.Option):
    """A click option whose help text is built when help is shown (``lazy_help``, a
    function returning it): a text that reads library defaults then imports the library
    only for ``--help``, not whenever the command module is loaded. A callable default
    (the library's constant, read when the command runs) is shown as its value."""

    def __init__(self, *args, lazy_help=None, **kw) -> None:
        super().__init__(*args, **kw)
        self._lazy_help = lazy_help

    def get_help_record(self, ctx):
        if self._lazy_help is not None:
            self.help = self._lazy_help()
        if not callable(self.default):
            return super().get_help_record(ctx)
        lazy, self.default = self.default, self.default()
        try:
            return super().get_help_record(ctx)
        finally:
            self.default = lazy


def _temp_c() -> float:
    from rangekit.physics import DEFAULT_TEMP_C

    return DEFAULT_TEMP_C


def _clock_ppm() -> float:
    from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM

    return DEFAULT_CLOCK_PPM


def transducer_q_options(type_: click.ParamType, default, help):
    """``--transducer-q`` (parameter ``q``) and the old ``--q``, hidden, kept for one release.

    The old spelling gives the same value with a one-line deprecation note on stderr;
    both at once are a usage error (exit 2). ``help`` is a text, or a function returning
    it (built when help is shown: :class:`LazyHelpOption`). Returns a decorator.
    """
    lazy = {"cls": LazyHelpOption, "lazy_help": help} if callable(help) else {"help": help}

    def deco(f):
        @click.option(
            "--transducer-q",
            "q",
            type=type_,
            default=default,
            show_default=default is not None,
            **lazy,
        )
        @click.option("--q", "q_deprecated", type=type_, default=None, hidden=True)
        @functools.wraps(f)
        def wrapper(*args, q_deprecated=None, **kw):
            if q_deprecated is not None:
                ctx = click.get_current_context()
                if ctx.get_parameter_source("q") == click.core.ParameterSource.COMMANDLINE:
                    raise click.UsageError("give --transducer-q only (--q is its old spelling)")
                kw["q"] = q_deprecated
                warn("rangekit: --q is deprecated and goes in the next release: --transducer-q")
            return f(*args, **kw)

        return wrapper

    return deco


def _beep_help(text: str, name: str) -> dict:
    """An option help ending in the default of :class:`rangekit.signals.Beep`'s ``name``,
    read when help is shown (:class:`LazyHelpOption`)."""

    def make() -> str:
        from rangekit.signals import Beep

        return f"{text} {shown_default(getattr(Beep(), name))}."

    return {"cls": LazyHelpOption, "lazy_help": make}


def beep_options(f):
    """--freq/--bursts/--spacing/--burst-len/--taper/--beep-fs: the beep that was played."""
    opts = [
        click.option(
            "--freq",
            "f_hz",
            type=FiniteRange(1.0, 1e7),
            default=None,
            **_beep_help("Beep frequency in Hz", "f_hz"),
        ),
        click.option(
            "--bursts",
            "n_bursts",
            type=click.IntRange(1, 64),
            default=None,
            **_beep_help(
                "Bursts per beep, at most 64 (the detectors' work grows with it)", "n_bursts"
            ),
        ),
        click.option(
            "--spacing",
            type=click.IntRange(1, 10**7),
            default=None,
            **_beep_help(
                "Samples between burst starts; the whole beep lasts at most 10 s", "spacing"
            ),
        ),
        click.option(
            "--burst-len",
            "burst_len",
            type=click.IntRange(8, 10**7),
            default=None,
            **_beep_help("Samples per burst", "burst_len"),
        ),
        click.option(
            "--taper",
            type=click.IntRange(0, 10**7),
            default=None,
            **_beep_help("Raised-cosine taper samples at each end", "taper"),
        ),
        click.option(
            "--beep-fs",
            "beep_fs",
            type=FiniteRange(1000.0, 1e7),
            default=None,
            **_beep_help("Sample rate the beep is defined at, Hz", "fs"),
        ),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


#: The options of :func:`beep_options`, by parameter name.
BEEP_OPTIONS = {
    "f_hz": "--freq",
    "n_bursts": "--bursts",
    "spacing": "--spacing",
    "burst_len": "--burst-len",
    "taper": "--taper",
    "beep_fs": "--beep-fs",
}


def refuse_beep_options(kw: dict) -> None:
    """Usage error if a beep option was given with ``--template`` (the probe replaces it)."""
    for key, opt in BEEP_OPTIONS.items():
        if kw.get(key) is not None:
            raise click.UsageError(f"{opt} describes the built-in beep; drop it or --template")


def make_beep(kw: dict, *, amplitude: float | None = None):
    """Build a Beep from the options of :func:`beep_options` (popped from ``kw``)."""
    from rangekit.signals import Beep

    args = {}
    for key, name in (
        ("f_hz", "f_hz"),
        ("n_bursts", "n_bursts"),
        ("spacing", "spacing"),
        ("burst_len", "burst_len"),
        ("taper", "taper"),
        ("beep_fs", "fs"),
    ):
        v = kw.pop(key, None)
        if v is not None:
            args[name] = v
    if amplitude is not None:
        args["amplitude"] = amplitude
    return Beep(**args)


def temperature_option(f):
    """--temperature C: air temperature (sets the speed of sound)."""
    return click.option(
        "--temperature",
        "temp_c",
        type=FiniteRange(-60.0, 60.0),
        cls=LazyHelpOption,
        default=_temp_c,  # rangekit.physics.DEFAULT_TEMP_C
        show_default=True,
        help="Air temperature, C.",
    )(f)


def make_burst(kw: dict, *, scheme: str):
    """:func:`rangekit_cli.ultrasonic_options.make_burst` (kept here for ``design``)."""
    from rangekit_cli.ultrasonic_options import make_burst as make

    return make(kw, scheme=scheme)


def detector_option(f):
    """--detector changepoint|xcorr (rangekit.detect.DETECTORS, tested equal)."""
    return click.option(
        "--detector",
        type=click.Choice(["changepoint", "xcorr"]),
        default="changepoint",
        show_default=True,
        help="Arrival detector for the beep: STFT change point + edge fit, or the whole-beep "
        "cross-correlation baseline.",
    )(f)


def output_option(f):
    """-o/--output FILE: results go there (atomically) instead of stdout."""
    return click.option(
        "-o",
        "--output",
        type=click.Path(dir_okay=False),
        default=None,
        help="Write here (atomically) instead of stdout; - is stdout. Refused: a link, a "
        "directory, a device or an input file.",
    )(f)


def format_choice(choices: tuple[str, ...] = FORMATS, default: str = "table"):
    """A ``--format`` option with the given choices (the command's output formats)."""

    def deco(f):
        return click.option(
            "--format",
            "fmt",
            type=click.Choice(choices),
            default=default,
            show_default=True,
            help="Output format.",
        )(f)

    return deco


format_option = format_choice()


def debug_option(f):
    """--debug on every command (also accepted before the command name)."""

    @click.option("--debug", is_flag=True, help="Show tracebacks of errors.")
    @functools.wraps(f)
    def wrapper(*args, debug: bool, **kw):
        ctx = click.get_current_context()
        if debug:
            ctx.find_root().meta["rangekit.debug"] = True
        guard_output(ctx, kw)
        return f(*args, **kw)

    return wrapper


#: ``ctx.find_root().meta`` key of the verbosity: -1 quiet, 0 normal, 1 verbose.
VERBOSITY_KEY = "rangekit.verbosity"


def verbosity_options(f):
    """``-q/--quiet`` and ``-v/--verbose`` on a command (one decorator for every verb).

    The flags are not passed to the command: it asks :func:`verbosity`, :func:`is_quiet`
    or :func:`is_verbose`, and writes to stderr through :func:`note` (dropped by
    ``--quiet``), :func:`detail` (only with ``--verbose``: what was chosen, e.g. the
    detector, the template, where the setup came from), :func:`note_after` (a note printed
    after the results) and :func:`warn` (always: a caveat about the results). Progress
    bars from :func:`progress` are off with ``--quiet``. Both flags at once are a usage
    error (exit 2). Errors are reported whatever the verbosity.
    """

    @click.option(
        "-q",
        "--quiet",
        "quiet",
        is_flag=True,
        help="No notes or progress on stderr (errors and warnings are still shown).",
    )
    @click.option(
        "-v",
        "--verbose",
        "verbose",
        is_flag=True,
        help="Also say on stderr what was chosen (detector, template, setup source, ...).",
    )
    @functools.wraps(f)
    def wrapper(*args, quiet: bool, verbose: bool, **kw):
        if quiet and verbose:
            raise click.UsageError("--quiet and --verbose exclude each other")
        ctx = click.get_current_context()
        ctx.find_root().meta[VERBOSITY_KEY] = -1 if quiet else (1 if verbose else 0)
        return f(*args, **kw)

    return wrapper


def verbosity() -> int:
    """-1 with ``--quiet``, 1 with ``--verbose``, 0 otherwise (or outside a command)."""
    ctx = click.get_current_context(silent=True)
    return 0 if ctx is None else int(ctx.find_root().meta.get(VERBOSITY_KEY, 0))


def is_quiet() -> bool:
    """Whether ``--quiet`` was given."""
    return verbosity() < 0


def is_verbose() -> bool:
    """Whether ``--verbose`` was given."""
    return verbosity() > 0


def note(msg: str) -> None:
    """A note on stderr (what was written, how long it took); dropped by ``--quiet``."""
    if not is_quiet():
        click.echo(msg, err=True)


def detail(msg: str) -> None:
    """What was chosen, on stderr, only with ``--verbose``."""
    if is_verbose():
        click.echo(msg, err=True)


def warn(msg: str) -> None:
    """A caveat about the results, on stderr, shown even with ``--quiet``."""
    click.echo(msg, err=True)


def note_after(msg: str) -> None:
    """A note printed on stderr after the command's results (dropped by ``--quiet``)."""
    if is_quiet():
        return
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        click.echo(msg, err=True)
    else:
        ctx.find_root().meta.setdefault("rangekit.notes", []).append(msg)


def progress(total: float, label: str, *, unit: str = ""):
    """A :class:`~rangekit_cli._progress.Progress` on stderr, or a silent one.

    Shown on a terminal; off with ``--quiet`` and when stderr is not a terminal (a log,
    a pipe), except with ``--verbose``, which writes a plain line every 30 s there.
    """
    import sys

    from rangekit_cli._progress import Progress

    tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
    on = not is_quiet() and (tty or is_verbose())
    return Progress(total, label, unit=unit, tty=tty, interval_s=None if on else math.inf)


def heartbeat(label: str):
    """A :class:`~rangekit_cli._progress.Heartbeat` (elapsed time of a job that cannot
    count its progress) on a terminal's stderr; off with ``--quiet`` or off a terminal."""
    import sys

    from rangekit_cli._progress import Heartbeat

    tty = bool(getattr(sys.stderr, "isatty", lambda: False)())
    return Heartbeat(label, tty=tty and not is_quiet())


def input_paths(ctx: click.Context, kw: dict) -> list[str]:
    """Every path the command reads: its arguments and its ``click.Path`` options other
    than ``-o`` (``a.wav+b.wav@0.5`` counts as ``a.wav`` and ``b.wav``)."""
    import re

    out: list[str] = []
    for p in ctx.command.params:
        if p.name == "output" or p.name not in kw:
            continue
        if not (isinstance(p, click.Argument) or isinstance(p.type, click.Path)):
            continue
        v = kw[p.name]
        for item in v if isinstance(v, (list, tuple)) else (v,):
            if isinstance(item, str):
                out.append(item)
                out.extend(t for t in re.split(r"[+@]", item) if t and t != item)
    return out


def check_outputs(paths) -> None:
    """:func:`rangekit.io.guard.check_output` for every file a command derives from
    ``-o`` (``synth``: ``NAME.json``, ``NAME_devI.wav``) against the command's inputs."""
    from rangekit.io.guard import check_output

    ctx = click.get_current_context()
    inputs = input_paths(ctx, ctx.params)
    for p in paths:
        check_output(p, inputs)


def _one_stdin(ctx: click.Context, kw: dict) -> None:
    """Usage error when ``-`` (standard input) is given for more than one input."""
    dashes = [p for p in input_paths(ctx, kw) if p == "-"]
    if len(dashes) > 1:
        raise click.UsageError(
            "- (standard input) is given for more than one input: a command reads standard "
            "input once; give the other inputs as files"
        )


def guard_output(ctx: click.Context, kw: dict) -> None:
    """Check ``-o`` before any work (every command, through :func:`debug_option`).

    At most one input may be ``-`` (standard input is read once; a usage error else).

    ``-o -`` is standard output (``kw["output"]`` becomes None) where ``-o`` is
    optional, a usage error where the command must write a file. Otherwise the output
    must not be a symbolic link, a directory, a device or a FIFO, nor the same file as
    any input (:func:`rangekit.io.guard.check_output`; exit 2), and its folder must exist
    (exit 3).
    """
    _one_stdin(ctx, kw)
    out = kw.get("output")
    if out is None:
        return
    param = next((p for p in ctx.command.params if p.name == "output"), None)
    if out == "-":
        if param is not None and not param.required:
            kw["output"] = None
            return
        raise click.UsageError(
            "-o - (standard output) is not possible here: this command writes a file"
        )
    from rangekit.io.guard import check_output

    check_output(out, input_paths(ctx, kw))


def float_list(
    text: str | None, *, name: str, lo: float = -math.inf, hi: float = math.inf
) -> list[float] | None:
    """Parse "0.1" or "0.1,0.12" into finite floats in [lo, hi]; usage errors name the option."""
    if text is None:
        return None
    try:
        vals = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise click.BadParameter(
            f"{text!r} is not a comma-separated list of numbers", param_hint=name
        ) from None
    if not vals:
        raise click.BadParameter(f"{text!r} holds no number", param_hint=name)
    for v in vals:
        if not (math.isfinite(v) and lo <= v <= hi):
            raise click.BadParameter(f"{v:g} is not within [{lo:g}, {hi:g}]", param_hint=name)
    return vals


def emit(text: str, output: str | None) -> None:
    """Write results to ``output`` atomically, or to stdout (None or ``-``)."""
    from rangekit.io.guard import printable

    text = printable(text)  # a non-UTF-8 file name must not break the output
    if output is None or output == "-":
        click.echo(text, nl=not text.endswith("\n"))
    else:
        from rangekit.io.sidecar import write_text_atomic

        write_text_atomic(output, text)


def self_distance_option(help: str):
    """--self-distance M[,M...] (string; parse with :func:`float_list`)."""
    return click.option(
        "--self-distance",
        "self_distance",
        metavar="M[,M...]",
        default="0",
        show_default=True,
        help=help,
    )


def speed_of_sound_option(help: str = "Speed of sound in m/s (overrides --temperature)."):
    """--speed-of-sound MPS (``speed``), None when not given."""
    return click.option(
        "--speed-of-sound",
        "speed",
        type=FiniteRange(100.0, 2000.0),
        default=None,
        metavar="MPS",
        help=help,
    )


def clock_ppm_option(help: str):
    """--clock-ppm PPM: 1-sigma sample-clock tolerance per device."""
    return click.option(
        "--clock-ppm",
        "clock_ppm",
        type=FiniteRange(0.0, 1e4),
        cls=LazyHelpOption,
        default=_clock_ppm,  # rangekit.ranging.beepbeep.DEFAULT_CLOCK_PPM
        show_default=True,
        help=help,
    )


TEMPLATE_HELP = (
    "The probe signal that was played (a mono WAV/FLAC, e.g. from `rangekit design sweep`), "
    "instead of the built-in beep; matched filtering with first-path selection; resampled "
    "to each recording's rate."
)


def template_option(f):
    """--template FILE (``template``): the probe that was played, None for the beep."""
    return click.option(
        "--template",
        "template",
        type=click.Path(),
        default=None,
        metavar="FILE",
        help=TEMPLATE_HELP,
    )(f)


def load_template(path: str | None):
    """The probe in the file ``path`` of :func:`template_option`, or None without one.

    Returns a :class:`~rangekit.signals.probe.Probe` (sample 0 = the emission's start,
    trailing silence dropped; :func:`~rangekit.signals.probe.read_probe`). Errors are the
    library's, one line naming the file: missing or unreadable (exit 3), not audio,
    multichannel or silent (exit 4).
    """
    if path is None:
        return None
    from rangekit.signals.probe import read_probe

    return read_probe(path)
