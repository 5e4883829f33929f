"""``rangekit experiment ... --format json`` marks the rows whose estimator read truth."""

from __future__ import annotations

import json

from clihelp import ok, run

from rangekit.experiments import ahn2007, girard2011


def test_girard2011_json_marks_oracle_rows(monkeypatch):
    monkeypatch.setattr(girard2011, "NUS", (150,))  # one walk, Table 1 only: fast
    doc = json.loads(ok(run(["experiment", "girard2011", "--trials", 1, "--seed", 1,
                             "--format", "json"])).stdout)  # fmt: skip
    oracle = [r for r in doc["rows"] if r["oracle"] is not None]
    plain = [r for r in doc["rows"] if r["oracle"] is None]
    assert all("oracle" in r for r in doc["rows"])
    assert {r["oracle"] for r in oracle} == {girard2011.ORACLE_START}
    assert all(r["metric"].endswith("(oracle start)") for r in oracle)
    assert not any("oracle" in r["metric"] for r in plain)
    # the same metric without the oracle, for both filters
    mu = {r["condition"] for r in plain if r["metric"] == "tracking error μ"}
    given = {f"with ranging, {m} ν=150, start within 0.5 m" for m in ("Girard", "SIR")}
    assert given <= mu and all(c in given or "model mismatch" in c for c in mu)
    table = ok(run(["experiment", "girard2011", "--trials", 1, "--seed", 1])).stdout
    assert "tracking error μ (oracle start)" in table


def test_ahn2007_json_marks_oracle_rows_and_gives_each_a_non_oracle_peer():
    doc = json.loads(ok(run(["experiment", "ahn2007", "--trials", 1, "--format", "json"])).stdout)
    oracle = [r for r in doc["rows"] if r["oracle"] is not None]
    assert {r["oracle"] for r in oracle} == {ahn2007._ORACLE_START, ahn2007._ORACLE_ANCHOR}
    assert all(r["metric"].endswith(("(oracle start)", "(oracle anchor)")) for r in oracle)
    plain = {(r["metric"], r["condition"]) for r in doc["rows"] if r["oracle"] is None}
    assert not any("oracle" in m for m, _ in plain)
    peer = {"online (oracle start)": "online from the first fix",
            "offline (oracle anchor)": "offline, i* from the fixes"}  # fmt: skip
    for r in oracle:
        if "literal" in r["condition"]:  # the text's r range read literally: context only
            continue
        ((o, p),) = [(o, p) for o, p in peer.items() if o in r["metric"]]
        assert (r["metric"].replace(o, p), r["condition"]) in plain
