"""Text forms of a binary phase code (the chips of a :class:`~rangekit.signals.barker.CodedBurst`).

A code is written as a Barker length (``"7"``: :data:`~rangekit.signals.barker.BARKER_CODES`)
or as its chips, ``+`` for +1 and ``-`` for -1 (``"++-"``). :func:`parse_code` reads
either; :func:`code_text` writes the shorter one (the Barker length when the code is one);
:func:`chips_text` always writes the chips. ``rangekit range --code`` and ``rangekit design
barker --code`` take this form, and the help texts show defaults in it.

Examples
--------
>>> parse_code("7")
(1, 1, 1, -1, -1, 1, -1)
>>> parse_code("+-+")
(1, -1, 1)
>>> code_text((1, 1, 1, -1, -1, 1, -1)), code_text((1,)), code_text((1, -1, 1))
('7', '+', '+-+')
>>> chips_text((1, 1, -1))
'++-'
>>> parse_code("6")
Traceback (most recent call last):
...
rangekit.errors.InvalidParameterError: no Barker code of length 6 (lengths: 2, 3, 4, 5, 7, 11, 13)
"""

from __future__ import annotations

from collections.abc import Sequence

from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import BARKER_CODES

__all__ = ["chips_text", "code_text", "parse_code"]


def parse_code(text: str) -> tuple[int, ...]:
    """The chips (+1/-1) of ``text``: a Barker length, or a string of ``+`` and ``-``.

    Raises
    ------
    InvalidParameterError
        A length with no Barker code, or text that is neither form (the message quotes
        it).
    """
    if text.strip().isdigit():
        n = int(text)
        if n not in BARKER_CODES:
            raise InvalidParameterError(
                f"no Barker code of length {n} (lengths: {', '.join(str(k) for k in BARKER_CODES)})"
            )
        return BARKER_CODES[n]
    if text and set(text) <= {"+", "-"}:
        return tuple(1 if ch == "+" else -1 for ch in text)
    raise InvalidParameterError(f"{text!r} must be a Barker length or a string of + and -")


def chips_text(code: Sequence[int]) -> str:
    """The chips of ``code`` as ``+`` and ``-`` (a positive chip is ``+``)."""
    return "".join("+" if c > 0 else "-" for c in code)


def code_text(code: Sequence[int]) -> str:
    """``code`` as its Barker length when it is a Barker code of length > 1, else its chips.

    The length-1 "Barker code" (a plain tone burst, the SRF02 ping) is written ``+``.
    """
    n = next((k for k, v in BARKER_CODES.items() if v == tuple(code) and k > 1), None)
    return str(n) if n is not None else chips_text(code)
