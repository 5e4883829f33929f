"""Comparison of two detections of one recording (importable through
``tests/detect/conftest.py``): the compiled kernels' against the numpy reference's."""

from __future__ import annotations

import numpy as np


def assert_same_detections(ref, fast, *, min_len: int = 1) -> None:
    """``fast`` and ``ref`` hold the same arrivals, at least ``min_len``: onsets and burst
    onsets within 1e-6 samples, sigma to 1e-9 relative, SNR within 1e-9 dB, flags and
    confidences equal."""
    assert len(ref) == len(fast) >= min_len
    np.testing.assert_allclose(fast.onset, ref.onset, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.sigma, ref.sigma, rtol=1e-9)
    np.testing.assert_allclose(fast.snr_db, ref.snr_db, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fast.flags, ref.flags)
    np.testing.assert_array_equal(fast.confidence, ref.confidence)
    np.testing.assert_allclose(fast.burst_onsets, ref.burst_onsets, rtol=0, atol=1e-6)
