"""The perturbation hook of the accuracy harnesses (issue 21; ``docs/perturbation.md``).

A test that compares an estimate with the truth passes its errors through :func:`worse`
right after computing them, before every assertion that reads them. Normally the factor is
1 and nothing changes (``x * 1.0`` is ``x`` bit for bit); ``benchmarks/perturb.py`` runs
the harnesses with ``RANGEKIT_TEST_WORSE=3``, i.e. as if the code under test returned
errors 3x the size of today's, and every such test must then fail: a bound that a 3x
worse result still meets checks nothing.

Harness files import it as ``from perturb import worse`` after putting ``tests/`` on
``sys.path`` (the tests run in pytest's importlib mode, as ``tests/cli/clihelp.py``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

#: The factor's environment variable (a float; 1 when unset).
FACTOR_ENV = "RANGEKIT_TEST_WORSE"
#: When set, the file to which :func:`worse` appends the node id of the test calling it
#: (``benchmarks/perturb.py`` uses it to tell the perturbed tests from the others).
LOG_ENV = "RANGEKIT_TEST_WORSE_LOG"


def worse(err):
    """``err * f`` with ``f = float($RANGEKIT_TEST_WORSE)`` (default 1), read at each call.

    ``err`` is an error (estimate - truth) or its magnitude: a float or an array. Sigmas
    and thresholds are not scaled: a 2-sigma coverage reads ``|worse(e)| <= 2 sigma``.
    """
    f = float(os.environ.get(FACTOR_ENV, "1"))
    log = os.environ.get(LOG_ENV)
    if log:
        test = os.environ.get("PYTEST_CURRENT_TEST", "?").rsplit(" (", 1)[0]
        with open(log, "a", encoding="utf-8") as fh:
            fh.write(test + "\n")
    if isinstance(err, list | tuple):
        err = np.asarray(err, dtype=np.float64)
    return err * f


def worse_rows(rows: Sequence[dict], key: str = "error_m") -> list[dict]:
    """Copies of a harness's result rows with ``row[key]`` passed through :func:`worse`."""
    return [{**r, key: worse(r[key])} for r in rows]
