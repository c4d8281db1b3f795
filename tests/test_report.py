"""Reports: the exit status decided once, and every format carrying every finding's stable ID."""

from __future__ import annotations

import json
from xml.etree import ElementTree

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.errors import ExitStatus
from meshcheck.outcome import CheckResult, exit_status
from meshcheck.reports import FORMATS, render, summary
from meshcheck.results import Finding, Location, PairVerdict, Part, Verdict, finding_id
from meshcheck.settings import Settings, resolve_fail_on

HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=50)


def make_result(
    *findings: Finding, clearance=None, checked_pairs=(), warnings=(), fail_on=None
) -> CheckResult:
    names = sorted({n for f in findings for n in (f.a, f.b)} | {"spare.stl"})
    parts = [Part(n, n.split("#")[0], 12, True, 1) for n in names]
    fail_on = resolve_fail_on(fail_on, clearance=clearance)
    settings = Settings(tolerance=1e-5, clearance=clearance, fail_on=fail_on)
    return CheckResult(
        findings=list(findings),
        parts=parts,
        settings=settings,
        checked_pairs=list(checked_pairs),
        warnings=list(warnings),
    )


def finding(a, b, status, *, approved=None, distance=0.0) -> Finding:
    interfering = status == "interference"
    verdict = PairVerdict(
        Verdict(status),
        distance,
        depth=0.7 if interfering else None,
        volume=2.5 if interfering else None,
        location=Location(np.array([1.0, 2, 3]), np.zeros(3), np.ones(3)),
    )
    return Finding(
        a=a,
        b=b,
        verdict=verdict,
        id=finding_id(a, "da", b, "db"),
        approval_reason=approved,
    )


CLASH = finding("bolt.stl", "plate.stl", "interference")
TOUCH = finding("bracket.stl", "plate.stl", "touching")
NEAR = finding("a.glb#pin", "a.glb#hub", "clearance", distance=0.1)
APPROVED = finding("nut.stl", "plate.stl", "interference", approved="press fit")


@pytest.mark.parametrize(
    ("findings", "clearance", "fail_on", "expected"),
    [
        ((), None, None, ExitStatus.OK),
        ((CLASH,), None, None, ExitStatus.FAILED),
        ((TOUCH,), None, None, ExitStatus.OK),
        ((TOUCH,), None, ("touching",), ExitStatus.FAILED),
        ((APPROVED,), None, None, ExitStatus.OK),
        ((APPROVED, TOUCH), None, ("interference", "touching"), ExitStatus.FAILED),
        ((NEAR,), None, None, ExitStatus.OK),
        ((NEAR,), 0.2, None, ExitStatus.FAILED),
        ((NEAR,), 0.2, ("interference",), ExitStatus.FAILED),  # --fail-on adds to the default
        ((CLASH,), None, ("touching",), ExitStatus.FAILED),  # interference always fails...
        ((CLASH,), None, (), ExitStatus.OK),  # ...unless `none` is given
    ],
)
def test_exit_status(findings, clearance, fail_on, expected):
    result = make_result(*findings, clearance=clearance, fail_on=fail_on)
    assert exit_status(result) == expected
    assert summary(result)["passed"] == (expected == ExitStatus.OK)


def test_finding_id_is_stable_and_order_free():
    assert finding_id("a", "1", "b", "2") == finding_id("b", "2", "a", "1")
    assert finding_id("a", "1", "b", "2") != finding_id("a", "1", "b", "3")
    assert len(finding_id("a", "1", "b", "2")) == 12


def test_json_follows_the_contract():
    doc = json.loads(render(make_result(CLASH, TOUCH, APPROVED), "json"))
    assert set(doc) == {"results", "groups", "parts", "summary"}
    for item in doc["results"]:
        assert {"a", "b", "status", "distance", "depth", "volume", "id"} <= set(item)
        assert item["status"] in ("interference", "touching", "clearance")
    clash = next(r for r in doc["results"] if r["a"] == "bolt.stl")
    assert clash == {**clash, "id": CLASH.id, "depth": 0.7, "volume": 2.5, "approved": None}
    touch = next(r for r in doc["results"] if r["a"] == "bracket.stl")
    assert touch["depth"] is None and touch["distance"] == 0.0
    s = doc["summary"]
    assert (s["interference"], s["touching"], s["approved"], s["failed"]) == (1, 1, 1, 1)
    assert (s["clearance"], s["required_clearance"]) == (0, None)
    assert s["passed"] is False


def test_text_lists_ids_and_ends_with_the_summary():
    text = render(make_result(CLASH, APPROVED), "text")
    lines = text.splitlines()
    assert lines[0].split()[:2] == ["ID", "STATUS"]
    assert any(line.startswith(CLASH.id) and "interference" in line for line in lines)
    row = next(k for k, line in enumerate(lines) if line.startswith(APPROVED.id))
    assert "interference (approved)" in lines[row]
    assert lines[row + 1].startswith(" " * 14 + "depth 0.7")  # the detail under its row
    assert lines[row + 1].endswith("approved: press fit")
    assert lines[-1].startswith("FAIL: 4 parts, 1 interference, 0 touching, 1 approved")


def test_junit_counts_failures_and_skips():
    result = make_result(CLASH, TOUCH, APPROVED, NEAR, clearance=0.2)
    root = ElementTree.fromstring(render(result, "junit"))
    suite = root.find("testsuite")
    cases = suite.findall("testcase")
    failed = [c for c in cases if c.find("failure") is not None]
    skipped = [c for c in cases if c.find("skipped") is not None]
    assert sorted(c.find("failure").get("type") for c in failed) == ["clearance", "interference"]
    assert [c.find("skipped").get("message") for c in skipped] == ["approved: press fit"]
    for element in (root, suite):
        assert element.get("tests") == str(len(cases))
        assert element.get("failures") == "2"
        assert element.get("skipped") == "1"
        assert element.get("errors") == "0"
    for f in (CLASH, TOUCH, APPROVED, NEAR):
        assert any(f.id in c.get("name") for c in cases)
    # the part with no finding is a passing test case
    assert any(c.get("name") == "spare.stl: no findings" for c in cases)


def test_junit_lists_clear_pairs_when_the_pipeline_names_them():
    pairs = [("bolt.stl", "plate.stl"), ("plate.stl", "spare.stl"), ("bolt.stl", "spare.stl")]
    root = ElementTree.fromstring(render(make_result(CLASH, checked_pairs=pairs), "junit"))
    names = sorted(c.get("name") for c in root.iter("testcase"))
    assert names == [
        f"bolt.stl <-> plate.stl [{CLASH.id}]",
        "bolt.stl <-> spare.stl",
        "plate.stl <-> spare.stl",
    ]
    assert root.get("failures") == "1"


def test_github_annotations():
    warnings = ["odd,file.stl: mesh is not closed"]
    result = make_result(CLASH, TOUCH, APPROVED, NEAR, warnings=warnings)
    lines = render(result, "github").splitlines()
    assert lines[0] == (
        f"::error file=bolt.stl,title=meshcheck interference [{CLASH.id}]::"
        "bolt.stl and plate.stl: interference, depth 0.7  volume 2.5  at (1, 2, 3)"
    )
    # errors, then warnings, then notices: the most severe first
    # a clearance finding without --clearance does not fail the run
    assert lines[1].startswith(f"::warning file=a.glb,title=meshcheck clearance [{NEAR.id}]")
    assert lines[2] == "::warning title=meshcheck input::odd,file.stl: mesh is not closed"
    assert lines[3].startswith(f"::notice file=bracket.stl,title=meshcheck touching [{TOUCH.id}]")
    notice = f"::notice file=nut.stl,title=meshcheck interference [{APPROVED.id}]"
    assert lines[4].startswith(notice)
    assert lines[4].endswith("(approved: press fit)")
    assert lines[-1].startswith("FAIL:")


def test_github_escapes_properties_and_data():
    odd = finding("dir,x/a:b.stl", "c.stl", "interference")
    part = Part(odd.a, odd.a, 12, True, 1)
    result = CheckResult([odd], [part], Settings(tolerance=1.0))
    line = render(result, "github").splitlines()[0]
    assert line.startswith("::error file=dir%2Cx/a%3Ab.stl,title=meshcheck interference")


def test_unknown_format_is_rejected():
    with pytest.raises(ValueError, match="unknown format"):
        render(make_result(), "yaml")


statuses = st.sampled_from(["interference", "touching", "clearance"])


@HYPOTHESIS
@given(
    spec=st.lists(st.tuples(statuses, st.booleans()), max_size=8),
    fail_on=st.lists(statuses, unique=True),
    fmt=st.sampled_from(FORMATS),
)
def test_every_format_agrees_with_the_exit_status(spec, fail_on, fmt):
    findings = [
        finding(f"p{k}.stl", f"q{k}.stl", status, approved="ok" if approved else None)
        for k, (status, approved) in enumerate(spec)
    ]
    result = make_result(*findings, clearance=0.5, fail_on=fail_on or None)
    failing_statuses = {"interference", "clearance", *fail_on}
    failing = sum(1 for s, approved in spec if s in failing_statuses and not approved)
    assert (exit_status(result) == ExitStatus.FAILED) == (failing > 0)
    out = render(result, fmt)
    for f in findings:
        assert f.id in out
    if fmt == "junit":
        assert ElementTree.fromstring(out).get("failures") == str(failing)
    elif fmt == "github":
        assert out.count("::error ") == failing
    elif fmt == "json":
        assert json.loads(out)["summary"]["failed"] == failing
    elif fmt == "sarif":
        levels = [r["level"] for r in json.loads(out)["runs"][0]["results"]]
        assert levels.count("error") == failing
    elif fmt == "markdown":
        assert out.startswith("## ❌ meshcheck: FAIL" if failing else "## ✅ meshcheck: PASS")
        assert out.count("| ❌ |") == failing
    else:
        assert out.splitlines()[-1].startswith("FAIL" if failing else "PASS")
