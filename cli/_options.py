"""Options shared by several commands, one import for the command modules.

Split by concern (each module parses options only; defaults and checks are the
library's): :mod:`rangekit_cli._options_types` (parameter types, help-text helpers,
``float_list``, ``number_option``), :mod:`rangekit_cli._options_output` (``-o``,
``--format``, ``--debug``, writing the results), :mod:`rangekit_cli._options_verbosity`
(``-q/-v``, stderr notes and progress), :mod:`rangekit_cli._options_signal` (beep, coded
burst, probe and detector options) and :mod:`rangekit_cli._options_setup` (air,
transducer, self-distance, clock and calibration options). This module re-exports them.
"""

from __future__ import annotations

from rangekit_cli._options_output import *  # noqa: F403
from rangekit_cli._options_output import __all__ as _output
from rangekit_cli._options_setup import *  # noqa: F403
from rangekit_cli._options_setup import __all__ as _setup
from rangekit_cli._options_signal import *  # noqa: F403
from rangekit_cli._options_signal import __all__ as _signal
from rangekit_cli._options_types import *  # noqa: F403
from rangekit_cli._options_types import __all__ as _types
from rangekit_cli._options_verbosity import *  # noqa: F403
from rangekit_cli._options_verbosity import __all__ as _verbosity

__all__ = [*_types, *_output, *_verbosity, *_signal, *_setup]
