"""``rangekit experiment ... --format json`` marks the rows whose estimator read truth."""

from __future__ import annotations

import json

from clihelp import ok, run

from rangekit.experiments import girard2011


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
    assert mu == {f"with ranging, {m} ν=150, start within 0.5 m" for m in ("Girard", "SIR")}
    table = ok(run(["experiment", "girard2011", "--trials", 1, "--seed", 1])).stdout
    assert "tracking error μ (oracle start)" in table
