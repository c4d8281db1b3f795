"""SARIF 2.1.0 for GitHub code scanning: one rule per status, one result per finding.

Each result names the file of the pair's first part as its artifact location (the second part's
file as a related location), carries the finding's stable ID as ``partialFingerprints`` (so code
scanning follows one clash across runs), its level (``error`` when it fails the run), approvals as
external suppressions, and with a baseline its ``baselineState`` (``new``, ``unchanged``; resolved
findings as ``absent``). An audited SRDF entry that disables a collision is a result on the SRDF's
line, with its witness pose. The run's properties hold the summary and, with robots, the ``pose``
each was checked at. Messages go through ``printable``; URIs are percent-encoded.

In a run of clash tests a finding's rule is its test's: ``TEST/STATUS`` (``fasteners/touching``),
one rule per test and status after the four plain ones (which the mechanisms colliding in motion
keep), each rule's default level from its test's ``fail_on``; every result names its ``test`` in
its properties and message.
"""

from __future__ import annotations

import json
import os
import urllib.parse
from collections.abc import Sequence

from ..outcome import CheckResult
from ..results import FINDING_STATUSES, Finding, Verdict
from .common import (
    View,
    audit_message,
    clash_test_line,
    describe,
    ordered,
    part_file,
    part_files,
    printable,
    resolution,
    summary_line,
    sweep_message,
)

SCHEMA = "https://json.schemastore.org/sarif-2.1.0.json"
FINGERPRINT = "meshcheckFindingId/v1"

_RULES = {
    Verdict.DUPLICATE: "Copies of one part placed at the same spot: a doubled component.",
    Verdict.INTERFERENCE: "Two parts share volume: they cannot both be built as modelled.",
    Verdict.CLEARANCE: "Two parts are closer than the required clearance.",
    Verdict.TOUCHING: "Two parts touch within the tolerance (contact, usually by design).",
}


def uri(path: str) -> dict:
    """An ``artifactLocation``: relative paths against the source root, absolute as file URIs."""
    raw = os.fsencode(path)  # a non-UTF-8 name keeps its bytes, percent-encoded
    if os.path.isabs(path):
        return {"uri": "file://" + urllib.parse.quote(raw)}
    return {"uri": urllib.parse.quote(raw.replace(b"\\", b"/")), "uriBaseId": "%SRCROOT%"}


def _level(result: CheckResult, finding: Finding) -> str:
    if result.is_failing(finding):
        return "error"
    return "note" if finding.is_approved or finding.status == Verdict.TOUCHING else "warning"


def _rule_ids(result: CheckResult) -> dict[str, int]:
    """Every rule's index by its ID: the four statuses, then ``TEST/STATUS`` for each clash
    test."""
    ids = [str(status) for status in FINDING_STATUSES]
    ids += [f"{t.name}/{status}" for t in result.tests for status in FINDING_STATUSES]
    return {rule: index for index, rule in enumerate(ids)}


def _rule_id(test: str, status) -> str:
    """The rule of a finding of ``status`` in clash test ``test`` (``""``: none)."""
    return f"{test}/{status}" if test else str(status)


def _result(
    result: CheckResult, f: Finding, paths: dict[str, str], tol: float | None, ids: dict[str, int]
) -> dict:
    detail = describe(f, tol)
    text = f"{printable(f.a)} and {printable(f.b)}: {f.status}, {detail}"
    if f.test:
        text = f"{printable(f.test)}: {text}"
    rule = _rule_id(f.test, f.status)
    entry = {
        "ruleId": rule,
        "ruleIndex": ids[rule],
        "level": _level(result, f),
        "message": {"text": text},
        "locations": [{"physicalLocation": {"artifactLocation": uri(part_file(paths, f.a))}}],
        "relatedLocations": [
            {
                "id": 1,
                "physicalLocation": {"artifactLocation": uri(part_file(paths, f.b))},
                "message": {"text": printable(f.b)},
            }
        ],
        "partialFingerprints": {FINGERPRINT: f.id},
        "properties": {
            "id": f.id,
            "a": f.a,
            "b": f.b,
            **_measurements(f),
            **({"test": f.test} if f.test else {}),
        },
    }
    if f.is_approved:
        entry["suppressions"] = [
            {"kind": "external", "justification": printable(f.approval_reason)}
        ]
    state = result.baseline_state(f)
    if state is not None:
        entry["baselineState"] = "new" if state == "new" else "unchanged"
    return entry


def _measurements(f: Finding) -> dict:
    doc = f.to_dict()
    return {k: doc[k] for k in ("distance", "depth", "volume", "tolerance", "location")}


def document(result: CheckResult) -> dict:
    from .. import __version__

    rules = [
        {
            "id": str(status),
            "name": str(status).capitalize(),
            "shortDescription": {"text": _RULES[status]},
            "defaultConfiguration": {"level": "error" if status in result.fail_on else "warning"},
        }
        for status in FINDING_STATUSES
    ]
    for test in result.tests:
        rules += [
            {
                "id": _rule_id(test.name, status),
                "name": f"{str(status).capitalize()} in {printable(test.name)}",
                "shortDescription": {
                    "text": f"{_RULES[status]} ({printable(clash_test_line(test))})"
                },
                "defaultConfiguration": {"level": "error" if status in test.fail_on else "warning"},
            }
            for status in FINDING_STATUSES
        ]
    ids = _rule_ids(result)
    paths = part_files(result)
    tol = resolution(result)
    results = [_result(result, f, paths, tol, ids) for f in ordered(result)]
    for robot, pair in result.failing_sweeps:  # a mechanism's parts collide in motion
        results.append(
            {
                "ruleId": str(pair.verdict),
                "ruleIndex": FINDING_STATUSES.index(pair.verdict),
                "level": "error",
                "message": {"text": f"in motion: {sweep_message(robot, pair)}"},
                "locations": [{"physicalLocation": {"artifactLocation": uri(robot.path)}}],
                "properties": {"a": pair.a, "b": pair.b, "pose": dict(pair.witness or {})},
            }
        )
    if result.audit is not None:  # SRDF entries that disable a collision, on their line
        for pair in result.audit.pairs:
            if not pair.is_wrong:
                continue
            location = {
                "artifactLocation": uri(result.audit.path),
                "region": {"startLine": pair.line},
            }
            results.append(
                {
                    "ruleId": str(pair.sweep.verdict),
                    "ruleIndex": FINDING_STATUSES.index(pair.sweep.verdict),
                    "level": "error" if result.is_failing_audit(pair) else "warning",
                    "message": {
                        "text": f"disables a collision: {audit_message(result.audit, pair)}"
                    },
                    "locations": [{"physicalLocation": location}],
                    "properties": {
                        "a": pair.a,
                        "b": pair.b,
                        "reason": pair.reason,
                        "pose": dict(pair.sweep.witness or {}),
                    },
                }
            )
    if result.baseline is not None:
        for r in result.baseline.resolved(result.findings):
            rule = _rule_id(r.test, r.status)
            rule = rule if rule in ids else str(r.status)  # its test is gone: the plain rule
            results.append(
                {
                    "ruleId": rule,
                    "ruleIndex": ids[rule],
                    "level": "none",
                    "message": {
                        "text": f"{printable(r.a)} and {printable(r.b)}: {r.status} resolved"
                    },
                    "partialFingerprints": {FINGERPRINT: r.id},
                    "baselineState": "absent",
                }
            )
    run = {
        "tool": {
            "driver": {
                "name": "meshcheck",
                "version": __version__,
                "informationUri": "https://pypi.org/project/meshcheck-assembly/",
                "rules": rules,
            }
        },
        "originalUriBaseIds": {"%SRCROOT%": {"uri": _srcroot()}},
        "invocations": [
            {
                "executionSuccessful": True,
                "toolExecutionNotifications": [
                    {"level": "warning", "message": {"text": printable(w)}} for w in result.warnings
                ],
            }
        ],
        "results": results,
        "properties": {"summary": summary_line(result)},
    }
    if result.poses:
        run["properties"]["pose"] = {p.path: p.to_dict() for p in result.poses}
    return {"$schema": SCHEMA, "version": "2.1.0", "runs": [run]}


def _srcroot() -> str:
    return "file://" + urllib.parse.quote(os.fsencode(os.getcwd())).rstrip("/") + "/"


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    return json.dumps(document(result), indent=2, ensure_ascii=True, allow_nan=False) + "\n"
