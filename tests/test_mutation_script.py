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


def test_a_pooled_sample_weighs_each_module_by_its_sites():
    mapped, unmapped = M.package_modules("rangekit/ranging")
    assert mapped and all(m.startswith("rangekit/ranging/") and m in M.TESTS for m in mapped)
    assert all(f not in M.TESTS for f in unmapped)
    n_sites = {m: len(M.sites((ROOT / m).read_text(encoding="utf-8"))) for m in mapped}
    total = sum(n_sites.values())
    # seeded, without replacement: the same draw twice, and no site twice
    a, b = M.pooled_sample(mapped, 300, 3), M.pooled_sample(mapped, 300, 3)
    assert a == b and sum(len(v) for v in a.values()) == 300
    assert all(len(set(v)) == len(v) for v in a.values())
    # each module's share within 4 binomial sigmas of its share of the sites
    # (hypergeometric: a bit tighter than binomial)
    for m, k in n_sites.items():
        p = k / total
        got = len(a.get(m, []))
        assert abs(got - 300 * p) <= 4 * (300 * p * (1 - p)) ** 0.5 + 1, (m, got, 300 * p)
    # the whole union when n exceeds it
    every = M.pooled_sample(mapped, total + 10, 0)
    assert sum(len(v) for v in every.values()) == total


def test_the_pooled_score_counts_every_module_and_names_the_unmapped(capsys):
    res = [
        {"module": "a.py", "sites": 10, "killed": 3, "valid": 4, "equivalent": 1},
        {"module": "b.py", "sites": 30, "killed": 5, "valid": 6, "equivalent": 0},
    ]
    out = M.pooled_summary("rangekit/ranging", res, 40, 7, [])
    assert out["killed"] == 8 and out["valid"] == 10 and out["score"] == 0.8
    assert out["score_without_equivalent"] == 8 / 9
    assert "8/10 = 80 %" in capsys.readouterr().out
    unmapped = M.package_modules("rangekit/detect")[1]
    out = M.pooled_summary("rangekit/detect", res, 40, 7, unmapped)
    assert set(out["unmapped"]) == set(unmapped)
    assert all(k > 0 for k in out["unmapped"].values())


def test_a_pooled_json_file_can_be_rerun(tmp_path):
    module = "rangekit/ranging/oneway.py"
    site = M.sites((ROOT / module).read_text(encoding="utf-8"))[0]
    mutant = {**M.asdict(site), "status": "survived", "seconds": 1.0}
    pooled = {"package": "rangekit/ranging", "sites": 1, "killed": 0, "valid": 1}
    f = tmp_path / "pooled.json"
    f.write_text(M.json.dumps([{"module": module, "mutants": [mutant]}, pooled]), "utf-8")
    assert M.survivors(f, module) == ([site], 0)
    assert M.survivors(f, "rangekit/ranging/echo.py") == ([], 0)
