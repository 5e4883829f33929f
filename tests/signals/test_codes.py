"""Text forms of a phase code (``rangekit.signals.codes``): what ``--code`` reads and the
help texts write."""

from __future__ import annotations

import pytest

from rangekit.errors import InvalidParameterError
from rangekit.signals.barker import BARKER_CODES
from rangekit.signals.codes import chips_text, code_text, parse_code


@pytest.mark.parametrize("n", sorted(BARKER_CODES))
def test_every_barker_length_round_trips(n):
    code = BARKER_CODES[n]
    assert parse_code(str(n)) == code
    assert parse_code(f" {n} ") == code  # spaces around a length are accepted
    if n > 1:
        assert code_text(code) == str(n)
    assert parse_code(chips_text(code)) == code


def test_chips_are_plus_and_minus():
    assert parse_code("+") == (1,)
    assert parse_code("+--+") == (1, -1, -1, 1)
    assert chips_text((1, -1, -1, 1)) == "+--+"
    # Not a Barker code: written as chips; the one-chip code (the SRF02 ping) too.
    assert code_text((1, -1, -1, 1)) == "+--+"
    assert code_text((1,)) == "+"
    # Barker 2 and the chips "+-" are the same code.
    assert code_text(parse_code("+-")) == "2"


@pytest.mark.parametrize(
    "text, match",
    [
        ("6", "no Barker code of length 6 \\(lengths: 2, 3, 4, 5, 7, 11, 13\\)"),
        ("0", "no Barker code of length 0"),
        ("", "'' must be a Barker length or a string of \\+ and -"),
        ("+x-", "'\\+x-' must be a Barker length"),
        ("7.0", "'7.0' must be a Barker length"),
    ],
)
def test_bad_text_is_refused_quoting_it(text, match):
    with pytest.raises(InvalidParameterError, match=match):
        parse_code(text)
