"""The curated top-level namespace (issue 19 item 2): sections, no shadowing, the reference page."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import rangekit

ROOT = Path(__file__).resolve().parents[1]
NAMES = [n for n in rangekit.__all__ if n != "__version__"]


def test_no_top_level_name_is_a_subpackage():
    subpackages = {m.name for m in pkgutil.iter_modules(rangekit.__path__)}
    assert "detect" in subpackages and "ranging" in subpackages
    assert not set(NAMES) & subpackages
    importlib.import_module("rangekit.detect")  # importing it must not change the name

    assert inspect.ismodule(rangekit.detect)
    assert rangekit.detect_arrivals is rangekit.detect.detect


@pytest.mark.parametrize("name", NAMES)
def test_every_name_resolves_with_a_signature(name):
    value = getattr(rangekit, name)
    assert value.__module__.startswith("rangekit"), name
    assert inspect.getdoc(value), f"{name} has no docstring"
    if not (inspect.isclass(value) and issubclass(value, BaseException)):
        inspect.signature(value)  # raises for anything that is not a plain callable


def test_reference_page_lists_every_name_in_its_section():
    text = (ROOT / "docs" / "api.md").read_text()
    sections = re.split(r"^## ", text, flags=re.M)[1:]
    found = {s.splitlines()[0].strip(): re.findall(r"^\| `(\w+)` \|", s, re.M) for s in sections}
    expected = {sec: list(names) for sec, names in rangekit.SECTIONS.items()}
    assert found == expected


def test_sections_and_all_agree():
    flat = [n for names in rangekit.SECTIONS.values() for n in names]
    assert len(flat) == len(set(flat))  # a name lives in one section
    assert sorted(flat) == sorted(NAMES)
    with pytest.raises(AttributeError, match="no attribute 'detect_beeps'"):
        rangekit.detect_beeps  # noqa: B018


def test_import_is_cheap():
    code = (
        "import sys, rangekit; rangekit.Beep; "
        "print('numba' in sys.modules, 'scipy.signal' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_invalid_parameter_errors_name_the_parameter():
    """The validators put the parameter's name on the error (``param``), which callers
    map to their own spelling (the CLI: ``--particles``) instead of reading the message."""
    import pytest

    from rangekit import _validate as V
    from rangekit.errors import InvalidParameterError
    from rangekit.localize.particle import MAX_PARTICLES, ParticleConfig

    for call in (
        lambda: V.positive("eps_m", -1.0),
        lambda: V.in_range("eps_m", 2.0, 0.0, 1.0),
        lambda: V.positive_int("eps_m", 0),
        lambda: V.positive("eps_m", "x"),
    ):
        with pytest.raises(InvalidParameterError) as e:
            call()
        assert e.value.param == "eps_m"
    for n in (0, MAX_PARTICLES + 1):
        with pytest.raises(InvalidParameterError) as e:
            ParticleConfig(n_particles=n)
        assert e.value.param == "n_particles"
    with pytest.raises(InvalidParameterError) as e:
        ParticleConfig(kappa=0)
    assert e.value.param == "kappa"
