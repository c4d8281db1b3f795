"""JUnit XML: one test case per finding, plus one per pair (or part) found clear.

A finding that fails the run is a ``<failure>``, an approved one is ``<skipped>``, others
(touching, unrequested clearance, findings a ``--fail-on new`` baseline holds) pass with their
measurements in ``<system-out>``. When the pipeline names the pairs it checked, each clear pair is
a passing test case; otherwise each part without findings is one. An audited SRDF entry is a
test case too, failed when it disables a collision (its witness pose in the message). The suite's
properties record the settings and, per robot, the ``pose`` it was checked at. XML 1.0 cannot
hold most control characters, so every name goes through ``printable``.

A run of clash tests has a ``testsuite`` per test, named after it, holding what the report of
that test alone would (its properties also name the test and its sides), then a ``meshcheck``
suite for the mechanisms colliding in motion, the SRDF audit and the warnings when there are any.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from xml.etree import ElementTree as ET

from ..outcome import CheckResult
from ..results import Finding
from .common import (
    View,
    audit_message,
    describe,
    ordered,
    part_files,
    pose_lines,
    printable,
    resolution,
    run_remainder,
    sections,
    sweep_message,
)


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    """The findings, then the clear pairs (or parts), as one ``testsuite``; one per clash
    test in a run of clash tests."""
    if result.tests:
        suites = [_suite(section, printable(section.test.name)) for section in sections(result)]
        rest = run_remainder(result)
        if rest.failing_sweeps or rest.warnings or rest.audit is not None:
            suites.append(_suite(rest, "meshcheck", has_clear_cases=False))
    else:
        suites = [_suite(result, "meshcheck")]
    keys = ("tests", "failures", "errors", "skipped", "time")
    counts = {k: str(sum(int(suite.get(k)) for suite in suites)) for k in keys}
    root = ET.Element("testsuites", name="meshcheck", **counts)
    root.extend(suites)
    ET.indent(root)
    body = ET.tostring(root, encoding="unicode")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + body + "\n"


def _suite(result: CheckResult, name: str, *, has_clear_cases: bool = True) -> ET.Element:
    """A ``testsuite`` of the result's findings, failing sweeps, clear pairs (or parts) and
    warnings, with the settings as properties."""
    paths = part_files(result)
    tol = resolution(result)
    cases = [_finding_case(result, f, paths, tol) for f in ordered(result)]
    cases.extend(_sweep_case(robot, pair) for robot, pair in result.failing_sweeps)
    cases.extend(_audit_cases(result))
    if has_clear_cases:
        cases.extend(_clear_cases(result))
    failures = sum(1 for c in cases if c.find("failure") is not None)
    skipped = sum(1 for c in cases if c.find("skipped") is not None)
    counts = {
        "tests": str(len(cases)),
        "failures": str(failures),
        "errors": "0",
        "skipped": str(skipped),
        "time": "0",
    }
    suite = ET.Element("testsuite", name=name, **counts)
    props = ET.SubElement(suite, "properties")
    for key, value in _settings(result).items():
        text = "" if value is None else printable(str(value))
        ET.SubElement(props, "property", name=key, value=text)
    for line in pose_lines(result):  # "pose PATH: values", a property per robot
        ET.SubElement(props, "property", name="pose", value=line.removeprefix("pose "))
    suite.extend(cases)
    if result.warnings:
        ET.SubElement(suite, "system-err").text = "\n".join(
            f"warning: {printable(w)}" for w in result.warnings
        )
    return suite


def _finding_case(
    result: CheckResult, f: Finding, paths: dict[str, str], tol: float | None
) -> ET.Element:
    """A finding's test case: failed, skipped (approved) or passed with its measurements."""
    a, b = printable(f.a), printable(f.b)
    case = ET.Element(
        "testcase",
        classname=f"meshcheck.{f.status}",
        name=f"{a} <-> {b} [{f.id}]",
        file=printable(paths.get(f.a, f.a.split("#")[0])),
        time="0",
    )
    message = f"{f.status}: {a} and {b}: {describe(f, tol)}"
    state = result.baseline_state(f)
    if state is not None:
        message += f" ({state} since the baseline)"
    props = ET.SubElement(case, "properties")
    for key, value in (("id", f.id), ("status", f.status), ("a", a), ("b", b)):
        ET.SubElement(props, "property", name=key, value=value)
    if state is not None:
        ET.SubElement(props, "property", name="baseline", value=state)
    if f.is_approved:
        ET.SubElement(case, "skipped", message=f"approved: {printable(f.approval_reason)}")
    elif result.is_failing(f):
        failure = ET.SubElement(case, "failure", message=message, type=f.status)
        # ASCII JSON: the names as data, with no character XML refuses
        failure.text = json.dumps(f.to_dict(), indent=2)
    else:
        ET.SubElement(case, "system-out").text = message
    return case


def _sweep_case(robot, pair) -> ET.Element:
    """A failed test case for a mechanism's pair that collides within its joint ranges."""
    case = ET.Element(
        "testcase",
        classname=f"meshcheck.sweep.{pair.verdict}",
        name=f"{printable(pair.a)} <-> {printable(pair.b)} [sweep]",
        file=printable(robot.path),
        time="0",
    )
    message = f"{pair.verdict} in motion: {sweep_message(robot, pair)}"
    ET.SubElement(case, "failure", message=message, type=str(pair.verdict))
    return case


def _audit_cases(result: CheckResult) -> list[ET.Element]:
    """A test case per audited SRDF entry: failed when it fails the run, else passed with what
    the sweep says of it."""
    audit = result.audit
    if audit is None:
        return []
    cases = []
    for pair in audit.pairs:
        case = ET.Element(
            "testcase",
            classname=f"meshcheck.srdf.{pair.status}",
            name=f"{printable(pair.a)} <-> {printable(pair.b)} [srdf {printable(pair.reason)}]",
            file=printable(audit.path),
            line=str(pair.line),
            time="0",
        )
        message = audit_message(audit, pair)
        if result.is_failing_audit(pair):
            message = f"disables a collision: {message}"
            ET.SubElement(case, "failure", message=message, type=str(pair.sweep.verdict))
        else:
            ET.SubElement(case, "system-out").text = f"{pair.status}: {message}"
        cases.append(case)
    return cases


def _clear_cases(result: CheckResult) -> list[ET.Element]:
    """A passing case per checked pair without a finding; per part when no pairs are named."""
    found = {(f.a, f.b) for f in result.findings}
    if result.checked_pairs:
        return [
            ET.Element(
                "testcase",
                classname="meshcheck.clear",
                name=f"{printable(a)} <-> {printable(b)}",
                time="0",
            )
            for a, b in sorted({tuple(sorted(p)) for p in result.checked_pairs} - found)
        ]
    named = {n for pair in found for n in pair}
    return [
        ET.Element(
            "testcase",
            classname="meshcheck.clear",
            name=f"{printable(part.name)}: no findings",
            file=printable(part.path),
            time="0",
        )
        for part in result.parts
        if part.name not in named
    ]


def _settings(result: CheckResult) -> dict:
    """The suite's properties: what the run (or clash test) checked and with which settings."""
    test = (
        {} if result.test is None else {"test": result.test.name, "sides": result.test.describe()}
    )
    return {
        **test,
        "parts": len(result.parts),
        "pairs_checked": len(result.checked_pairs),
        "tolerance": result.tolerance,
        "clearance": result.clearance,
        "units": result.units,
        "fail_on": ",".join(result.fail_on) + (",new" if result.settings.fail_on_new else ""),
        "config": result.settings.config_path,
        "baseline": None if result.baseline is None else result.baseline.path,
    }
