"""Parameter types and help-text helpers shared by the commands' options."""

from __future__ import annotations

import math

import click

__all__ = [
    "FiniteRange",
    "LazyHelpOption",
    "QOrAuto",
    "doc_page",
    "float_list",
    "id_list",
    "library_default",
    "library_help",
    "number_option",
    "shown_default",
]


def shown_default(value) -> str:
    """A default in a help text, the one way every ``--help`` shows them.

    >>> shown_default(0.05), shown_default("no gate")
    ('[default: 0.05]', '[default: no gate]')
    """
    return f"[default: {value:g}]" if isinstance(value, float) else f"[default: {value}]"


def library_default(path: str, name: str | None = None):
    """A default of the library, read where it is defined instead of copied: the default
    of field or keyword ``name`` of the dataclass or function at ``path``
    (``"module:attr"``), or with no ``name`` the constant there.

    >>> library_default("rangekit.signals.barker:CodedBurst", "carrier_hz")
    40000.0
    >>> library_default("rangekit.signals.probe:DEFAULT_FADE_S")
    0.005
    """
    import importlib
    import inspect

    module, attr = path.split(":")
    obj = getattr(importlib.import_module(module), attr)
    if name is None:
        return obj
    fields = getattr(obj, "__dataclass_fields__", None)
    if fields is not None:
        return fields[name].default
    return inspect.signature(obj).parameters[name].default


def library_help(text: str, value) -> dict:
    """``cls`` and ``lazy_help`` of an option whose help is ``text`` and then the default
    ``value()`` (e.g. a :func:`library_default`) as every help shows defaults, read when
    help is shown (so the command module imports no library)."""
    return {"cls": LazyHelpOption, "lazy_help": lambda: f"{text} {shown_default(value())}."}


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


def number_option(
    *decls: str,
    lo: float | None,
    hi: float | None,
    metavar: str,
    min_open: bool = False,
    **kw,
):
    """A ``click.option`` taking one finite number in [lo, hi] (:class:`FiniteRange`;
    ``min_open``: lo itself refused; None: no bound), shown as ``metavar``.

    The default is None (not given: the library's default applies) unless ``kw`` gives
    one; every other keyword (``help``, ``show_default``, ``cls``, ...) is click's.
    """
    kw.setdefault("default", None)
    return click.option(*decls, type=FiniteRange(lo, hi, min_open=min_open), metavar=metavar, **kw)


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


def id_list(text: str | None, *, name: str) -> tuple[int, ...] | None:
    """Parse "4" or "0,1,2" into whole numbers in [0, 1e6] (ids); usage errors name the option."""
    vals = float_list(text, name=name, lo=0, hi=1e6)
    if vals is None:
        return None
    if any(v != int(v) for v in vals):
        raise click.BadParameter("ids must be whole numbers", param_hint=name)
    return tuple(int(v) for v in vals)
