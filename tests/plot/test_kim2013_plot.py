"""rangekit.plot.kim2013: Figs 8/10-like error panels and the path panels are written."""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.experiments.kim2013 import _trial
from rangekit.plot.kim2013 import plot_errors, plot_paths


@pytest.fixture(scope="module")
def trial():
    return _trial(4, np.random.SeedSequence(0))


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_plot_errors_writes_file(tmp_path, trial, suffix):
    out = tmp_path / f"errors{suffix}"
    plot_errors(trial, out, title="Trajectory 4 (Fig. 10)")
    assert out.is_file() and out.stat().st_size > 0
    if suffix == ".svg":
        text = out.read_text()
        for label in ("E_p (m)", "E_phi (deg)", "Tx id", "time (s)", "Trajectory 4"):
            assert label in text


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_plot_paths_writes_file(tmp_path, trial, suffix):
    out = tmp_path / f"paths{suffix}"
    plot_paths({4: trial}, out)
    assert out.is_file() and out.stat().st_size > 0
    if suffix == ".svg":
        text = out.read_text()
        for label in ("x (m)", "y (m)", "trajectory 4", "DUHL"):
            assert label in text


def test_plot_paths_two_by_two(tmp_path, trial):
    out = tmp_path / "paths4.png"
    plot_paths({k: trial for k in (1, 2, 3, 4)}, out)
    assert out.stat().st_size > 0
