"""``rangekit.detect.pathfit``'s rules that its fit tests do not pin (issue 21, the mutation
check): the parabolic vertex of the path scan, and the misfit of an in-model arrival
(noise-corrected: about 0, not the noise's own energy). About a second.
"""

from __future__ import annotations

import numpy as np
import pytest

from rangekit.detect import pathfit as P
from rangekit.detect.fitted import transducer_models
from rangekit.detect.matched import coded_template, detect_matched
from rangekit.signals.barker import CodedBurst
from rangekit.signals.transducer import Transducer

FS = 192000.0


def test_interp_is_the_parabolas_vertex_clipped_to_half_a_sample():
    z = -((np.arange(20.0) - 10.3) ** 2)
    assert P._interp(z, 10) == pytest.approx(10.3, abs=1e-12)
    z = -((np.arange(20.0) - 9.8) ** 2)
    assert P._interp(z, 10) == pytest.approx(9.8, abs=1e-12)
    assert P._interp(-((np.arange(20.0) - 12.0) ** 2), 10) == 10.5  # not the top: clipped
    assert P._interp(-((np.arange(20.0) - 8.0) ** 2), 10) == 9.5
    assert P._interp(np.arange(20.0), 10) == 10.0  # no curvature
    assert P._interp(z, 0) == 0.0 and P._interp(z, 19) == 19.0


def test_misfit_of_an_in_model_arrival_is_noise_corrected():
    """Six Q 4 arrivals in white noise of 2 % of the peak, fitted with the resonator
    model they come from: the misfit (the energy the model leaves unexplained beyond the
    noise, over the fitted signal's) is within 2.5e-3 of 0 (measured |misfit| <= 1.1e-3 at
    |misfit_z| <= 2.5; the noise's own energy would be ~1e-2)."""
    t = Transducer()
    h = coded_template(fs=FS, tx=t, rx=t)
    models, _ = transducer_models(CodedBurst(), fs=FS, transducers=(t, t))
    rng = np.random.default_rng(3)
    sigma = 0.02 * np.abs(h).max()
    for w in range(6):
        x = sigma * rng.standard_normal(12000)
        x[6000 : 6000 + len(h)] += h
        (on,) = detect_matched(x, fs=FS, template=h).onset
        f = P.fit_arrival(x, on, model=models[0], sigma=sigma, q0=4.0, lo=0, hi=12000)
        assert abs(f.misfit) < 2.5e-3 and abs(f.misfit_z) < 4.0, (w, f.misfit, f.misfit_z)
