"""``benchmarks/mutation.py`` itself: every module it maps exists with its tests, and every
survivor it lists as an equivalent mutant names a mutation site still in its module (an
entry whose line changed must be judged again, not counted silently)."""

from __future__ import annotations

import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import mutation as M  # noqa: E402


def test_every_mapped_module_and_test_file_exists():
    for module, tests in M.TESTS.items():
        assert (ROOT / module).is_file(), module
        assert tests and all((ROOT / t).is_file() for t in tests), module


def test_equivalent_entries_name_live_sites():
    for module, entries in M.EQUIVALENT.items():
        assert module in M.TESTS, module
        source = (ROOT / module).read_text(encoding="utf-8")
        lines = source.splitlines()
        all_sites = M.sites(source)
        live = {M.site_key(s, lines, all_sites) for s in all_sites}
        for key, why in entries.items():
            assert key in live, (module, key)  # a 2-tuple only where the pair is unique
            assert why.strip(), (module, key)


def test_a_repeated_mutation_on_one_line_is_keyed_by_its_place():
    lines = ["x = a - b - c", "y = a - b"]
    all_sites = M.sites("\n".join(lines))
    minus = [s for s in all_sites if s.what == "- -> +"]
    keys = [M.site_key(s, lines, all_sites) for s in minus]
    assert sorted(keys) == [("x = a - b - c", "- -> +", 0), ("x = a - b - c", "- -> +", 1),
                            ("y = a - b", "- -> +")]  # fmt: skip
    # index 0 is the leftmost operator: (a - b) - c's inner one
    first = next(s for s, k in zip(minus, keys, strict=True) if k[2:] == (0,))
    assert first.col == min(s.col for s in minus if s.line == 1)


def test_summary_sets_equivalent_survivors_apart():
    module = "rangekit/detect/condition.py"
    source = (ROOT / module).read_text(encoding="utf-8")
    lines = source.splitlines()
    all_sites = M.sites(source)
    eq = next(s for s in all_sites if (lines[s.line - 1].strip(), s.what) in M.EQUIVALENT[module])
    other = next(s for s in all_sites if (lines[s.line - 1].strip(), s.what)
                 not in M.EQUIVALENT[module])  # fmt: skip
    out = [M.Outcome(eq, "survived", 0.0), M.Outcome(other, "survived", 0.0)]
    out += [M.Outcome(other, "killed", 0.0)] * 2
    res = M.summary(module, out, len(all_sites), 0)
    assert (res["killed"], res["valid"], res["equivalent"]) == (2, 4, 1)
    assert res["score"] == 0.5 and res["score_without_equivalent"] == 2 / 3
