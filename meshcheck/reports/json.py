"""The JSON report: ``results``, ``groups``, ``parts`` and ``summary``; names kept whole.

``groups`` are the clash groups (``results.clash_groups``): each has its ``kind`` (``part``: a
part its findings share, named in ``part``; ``pattern``: copies of two parts at one relative
placement, ``part`` null), its status and its findings' IDs.

With ``--sweep`` the document also has ``sweeps``: per robot (or ``[[joint]]`` mechanism) the
counts by class and every link pair, each with its ``pose`` (the witness's joint values, for a
``sometimes`` pair; see ``results.PairSweep``).

With ``--audit-srdf`` it has ``audit``: the SRDF, the robot, the reasons audited, the counts by
sweep status and every audited entry (its links, reason, line, status, whether it is ``wrong``
and ``failed``, and the witness ``pose``; ``results.AuditedPair``). ``summary.pose`` records the
joint values every robot was checked at.

Every finding carries ``baseline`` (``"new"``, ``"active"``, or null without a baseline); with a
baseline the document also has ``resolved``, the baseline's findings this run no longer has.

A run of clash tests also has ``tests``: per test its ``name``, sides ``a`` and ``b`` (patterns),
``clearance``, ``tolerance`` (null: per pair), ``fail_on``, ``passed``, the IDs of its
``findings`` and ``groups`` (most severe first), and its ``summary`` (as a run of that test alone
would have it); every finding and group carries its ``test``, and ``results`` and ``groups``
list those of all the tests.
Output is ASCII (``\\uXXXX`` escapes), so any name survives any terminal or file encoding.
"""

from __future__ import annotations

import json
from collections.abc import Sequence

from ..outcome import CheckResult
from ..results import clash_groups
from .common import View, ordered, sections, summary


def document(result: CheckResult) -> dict:
    """The report as a JSON-ready dict."""
    findings = ordered(result)
    results = []
    for f in findings:
        entry = f.to_dict()
        entry["baseline"] = result.baseline_state(f)
        entry["failed"] = result.is_failing(f)
        results.append(entry)
    doc = {
        "results": results,
        "groups": [g.to_dict() for g in clash_groups(findings)],
        "parts": [p.to_dict() for p in result.parts],
        "summary": summary(result),
    }
    if result.sweeps:  # --sweep: every link pair's class, a witness pose for sometimes
        doc["sweeps"] = [r.to_dict() for r in result.sweeps]
        for robot, entry in zip(result.sweeps, doc["sweeps"], strict=True):
            for pair, row in zip(robot.pairs, entry["pairs"], strict=True):
                row["failed"] = result.is_failing_sweep(robot, pair)
    if result.audit is not None:  # --audit-srdf: every audited entry, a witness for the wrong
        doc["audit"] = result.audit.to_dict()
        for pair, row in zip(result.audit.pairs, doc["audit"]["pairs"], strict=True):
            row["failed"] = result.is_failing_audit(pair)
    if result.baseline is not None:
        doc["resolved"] = [r.to_dict() for r in result.baseline.resolved(result.findings)]
    if result.tests:
        doc["tests"] = [_test(section) for section in sections(result)]
    return doc


def _test(section: CheckResult) -> dict:
    """A clash test's entry: its settings, its findings' and groups' IDs, its summary."""
    test = section.test
    findings = ordered(section)
    return {
        "name": test.name,
        "a": list(test.sides.a),
        "b": list(test.sides.b),
        "clearance": test.clearance,
        "tolerance": test.tolerance,
        "fail_on": [str(s) for s in test.fail_on],
        "passed": section.passed,
        "findings": [f.id for f in findings],
        "groups": [g.id for g in clash_groups(findings)],
        "summary": summary(section),
    }


def render(result: CheckResult, *, inputs: Sequence[str] = (), view: View | None = None) -> str:
    return json.dumps(document(result), indent=2, ensure_ascii=True, allow_nan=False) + "\n"
