"""Two-way ranging's bound on onsets and sigmas (MAX_ONSET_S = 1e7 s), at its edge.

Written against the mutants of ``rangekit/ranging/beepbeep.py`` that its other tests let
through on 2026-12-02 (``benchmarks/mutation.py``, docs/evidence.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.errors import InvalidParameterError
from rangekit.ranging import range_beepbeep
from rangekit.ranging.beepbeep import MAX_ONSET_S
from rangekit.types import Arrivals


def _pair(last_s, sigma_s=1e-4):
    """Two devices 1 s apart at fs = 1 Hz; device 1 hears its own beep at ``last_s``."""

    def arr(onsets):
        z = np.zeros(2)
        return Arrivals(np.asarray(onsets, float), 1.0, z + sigma_s, z + 30, z + 1,
                        np.zeros((2, 4)))  # fmt: skip

    return [arr([0.0, last_s - 1.0]), arr([1.0, last_s])]


def test_onsets_and_sigmas_up_to_1e7_s_are_accepted_and_beyond_refused():
    assert MAX_ONSET_S == 1e7
    range_beepbeep(_pair(1e7), speed_m_s=343.0)  # exactly at the bound
    range_beepbeep(_pair(10.0, sigma_s=1e7), speed_m_s=343.0)
    for bad in (_pair(1.5e7), _pair(np.nextafter(1e7, np.inf)), _pair(10.0, sigma_s=1.5e7)):
        with pytest.raises(InvalidParameterError, match="within 1e\\+07 s"):
            range_beepbeep(bad, speed_m_s=343.0)
