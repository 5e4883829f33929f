"""Perturbation check: does each accuracy harness fail when its subject is 3x worse?

The accuracy, consistency and calibration tests that compare an estimate with the truth
pass their errors through ``tests/perturb.py``'s :func:`worse` (``err * f``, ``f`` from
``$RANGEKIT_TEST_WORSE``, 1 by default) before every assertion that reads them. This
script runs each harness file (the test files that import ``perturb``) in a subprocess
with ``RANGEKIT_TEST_WORSE=3`` (``--factor``) and reports, per test:

* ``1x``: its outcome in a normal run (a run of the same file at factor 1, or the JUnit XML
  of an earlier normal run given with ``--baseline``);
* ``3x``: its outcome with the errors scaled (required: failed);
* whether it called :func:`worse` (``perturbed``): a test of a harness file that reads no
  error against the truth (a flag, a count of detections, the time origin of a control) is
  listed as ``not perturbed`` and does not enter the verdict.

The verdict is ``PASS`` when every perturbed test passes (or xfails) at 1x and fails at the
factor; the exit status is 1 when a perturbed test passes at the factor (its bounds cannot
see a 3x regression) or fails at 1x (the check means nothing then), else 0.

Not part of CI: it runs every harness file twice (about 6.5 minutes here). Run it
niced on shared machines (it lowers its own priority by 10)::

    python benchmarks/perturb.py                      # every harness file, 1x and 3x
    python benchmarks/perturb.py --only test_accuracy  # node ids containing the text
    python benchmarks/perturb.py --baseline base.xml   # 1x from `pytest --junitxml=base.xml`

Each file runs as ``python -m pytest FILE -n 0 -q -p no:cacheprovider`` (no ``-x``: every
test of the file runs). The method and the last table are in ``docs/perturbation.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: The text a harness file holds (its import of the hook).
MARK = "from perturb import"


def harness_files() -> list[str]:
    """Test files (relative to the repository) that import ``tests/perturb.py``."""
    out = []
    for p in sorted((ROOT / "tests").rglob("test_*.py")):
        if MARK in p.read_text(encoding="utf-8"):
            out.append(p.relative_to(ROOT).as_posix())
    return out


def _collect(path: str) -> list[str]:
    """The node ids of one test file (``pytest --collect-only -q``)."""
    cmd = [sys.executable, "-m", "pytest", path, "--collect-only", "-q", "-n", "0",
           "-p", "no:cacheprovider"]  # fmt: skip
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    return [ln.strip() for ln in res.stdout.splitlines() if ln.startswith(path + "::")]


def parse_junit(xml_path: pathlib.Path, messages: dict | None = None) -> dict[str, str]:
    """Node id -> outcome (passed, failed, error, skipped, xfailed) of a JUnit XML file;
    a failure's message (its first line, e.g. ``assert 0.0016 <= 0.0012``) is stored in
    ``messages`` when given."""
    out: dict[str, str] = {}
    for case in ET.parse(xml_path).getroot().iter("testcase"):
        parts = case.get("classname", "").split(".")
        name = case.get("name", "")
        # classname: the module's dotted path, then any classes; find the file.
        node = None
        for k in range(len(parts), 0, -1):
            f = "/".join(parts[:k]) + ".py"
            if (ROOT / f).is_file():
                node = "::".join([f, *parts[k:], name])
                break
        if node is None:
            continue
        outcome = "passed"
        for child in case:
            if child.tag in ("failure", "error"):
                outcome = "failed" if child.tag == "failure" else "error"
                if messages is not None:
                    messages[node] = (child.get("message") or "").split("\n")[0][:200]
            elif child.tag == "skipped":
                outcome = "xfailed" if child.get("type") == "pytest.xfail" else "skipped"
        # A test with a failing teardown has two entries: keep the worse outcome.
        if out.get(node) in ("failed", "error"):
            continue
        out[node] = outcome
    return out


def run_file(
    path: str, factor: float, nodes: list[str] | None, messages: dict | None = None
) -> tuple[dict, set]:
    """Outcomes of one file's tests at ``factor`` and the node ids that called worse()."""
    with tempfile.TemporaryDirectory() as tmp:
        xml = pathlib.Path(tmp) / "junit.xml"
        log = pathlib.Path(tmp) / "worse.log"
        env = {**os.environ, "RANGEKIT_TEST_WORSE": repr(float(factor)),
               "RANGEKIT_TEST_WORSE_LOG": str(log)}  # fmt: skip
        cmd = [sys.executable, "-m", "pytest", *(nodes or [path]), "-n", "0", "-q",
               "-p", "no:cacheprovider", f"--junitxml={xml}"]  # fmt: skip
        subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, check=False)
        outcomes = parse_junit(xml, messages) if xml.is_file() else {}
        called = set(log.read_text(encoding="utf-8").split("\n")) - {""} if log.is_file() else set()
    return outcomes, called


def verdict(one: str | None, many: str | None, perturbed: bool) -> str:
    """One test's line: ok, BLIND (passes at the factor), or why it does not count."""
    if not perturbed:
        return "not perturbed"
    if one not in ("passed", "xfailed"):
        return f"BASELINE {one or 'missing'}"
    if many in ("failed", "error"):
        return "ok"
    return "BLIND" if many in ("passed", "xfailed") else f"? {many}"


def main(argv: list[str] | None = None) -> int:
    """Run the check; print the table and the verdict; 1 if a harness cannot see 3x."""
    ap = argparse.ArgumentParser(
        prog="python benchmarks/perturb.py", description=__doc__.split("\n")[0]
    )
    ap.add_argument(
        "files", nargs="*", help="harness files (default: every test file importing perturb)"
    )
    ap.add_argument("--factor", type=float, default=3.0, help="error factor (default 3)")
    ap.add_argument("--only", default=None, help="only node ids containing this text")
    ap.add_argument(
        "--baseline",
        type=pathlib.Path,
        default=None,
        help="JUnit XML of a normal run: its 1x outcomes (default: run each file at 1x)",
    )
    ap.add_argument("--json", type=pathlib.Path, default=None, help="write the rows here")
    a = ap.parse_args(argv)
    os.nice(10)
    base = parse_junit(a.baseline) if a.baseline else None
    rows = []
    for path in a.files or harness_files():
        nodes = None
        if a.only:
            nodes = [n for n in _collect(path) if a.only in n]
            if not nodes:
                continue
        print(f"# {path}: factor {a.factor:g}" + ("" if base else " and 1"), flush=True)
        msg1: dict[str, str] = {}
        msg: dict[str, str] = {}
        many, called = run_file(path, a.factor, nodes, msg)
        if base is None:
            one, called1 = run_file(path, 1.0, nodes, msg1)
            called |= called1
        else:
            one = base
        mine = set(many) if base else set(many) | set(one)
        for node in sorted(n for n in mine if not a.only or a.only in n):
            r = {"test": node, "1x": one.get(node), f"{a.factor:g}x": many.get(node),
                 "perturbed": node in called}  # fmt: skip
            r["verdict"] = verdict(r["1x"], r[f"{a.factor:g}x"], r["perturbed"])
            r["message_1x"], r["message"] = msg1.get(node), msg.get(node)
            rows.append(r)
            print(f"  {r['verdict']:14s} {node}", flush=True)
            if r["verdict"].startswith("BASELINE") and r["message_1x"]:
                print(f"                 1x: {r['message_1x']}", flush=True)
    k = f"{a.factor:g}x"
    print(f"\n| test | 1x | {k} | verdict |\n|---|---|---|---|")
    for r in rows:
        print(f"| `{r['test']}` | {r['1x']} | {r[k]} | {r['verdict']} |")
    counted = [r for r in rows if r["perturbed"]]
    bad = [r for r in counted if r["verdict"] != "ok"]
    print(
        f"\n{len(counted)} perturbed tests ({len(rows) - len(counted)} not perturbed): "
        f"{len(counted) - len(bad)} fail at {k} as they must, {len(bad)} do not"
    )
    for r in bad:
        print(f"  {r['verdict']}: {r['test']}")
    print("verdict:", "PASS" if counted and not bad else "FAIL")
    if a.json:
        a.json.write_text(json.dumps({"factor": a.factor, "rows": rows}, indent=1) + "\n")
    return 0 if counted and not bad else 1


if __name__ == "__main__":
    raise SystemExit(main())
